// tcfarm dashboard: the jobs (filtered, searched, a page at a time), the selected job's
// figures, frames, events and actions, and the workers. Live: the farm's event stream
// (GET /api/v1/events) says when something happened, and the page fetches what changed;
// without the stream it polls every second. Charts are Chart.js (node_modules/chart.js,
// installed from npm by scripts/bootstrap). api.js talks to the API, submit.js submits.
"use strict";

const POLL_MS = 1000;       // without the event stream
const LIVE_POLL_MS = 5000;  // with it: the workers' figures, which have no events
const REFRESH_DELAY_MS = 150;  // events come in bursts (frames written): one fetch per burst
const EVENTS_SHOWN = 200;

const state = {
  jobId: null,          // the selected job
  job: null,            // its last record
  jobs: [],             // the job list's current page
  frame: null,          // the frame the images show
  follow: true,         // the images follow the latest finished frame
  charts: {},
  filters: { state: "", strategy: "", name: "" },
  offset: 0,
  limit: 20,
  total: 0,
  stream: "connecting", // the event stream: live, connecting, absent, error
  events: [],           // the selected job's events, oldest first
  hasEvents: true,      // whether the farm keeps events (a farm without answers 404)
  autoSelect: true,     // select the newest job while none is chosen (not after a delete)
};

// --- helpers -------------------------------------------------------------------------

const $ = (id) => document.getElementById(id);

function el(tag, attrs = {}, children = []) {
  const node = document.createElement(tag);
  for (const [key, value] of Object.entries(attrs)) {
    if (key === "text") node.textContent = value;
    else if (key === "class") node.className = value;
    else node.setAttribute(key, value);
  }
  for (const child of children) node.appendChild(child);
  return node;
}

function fixed(value, digits) {
  return typeof value === "number" && isFinite(value) ? value.toFixed(digits) : "–";
}

function seconds(value) {
  if (typeof value !== "number" || !isFinite(value)) return "–";
  return value < 10 ? value.toFixed(2) + " s" : value.toFixed(1) + " s";
}

function rate(pixelsPerSecond) {
  if (!isFinite(pixelsPerSecond) || pixelsPerSecond <= 0) return "–";
  if (pixelsPerSecond >= 1e6) return (pixelsPerSecond / 1e6).toFixed(2) + " Mpx/s";
  if (pixelsPerSecond >= 1e3) return (pixelsPerSecond / 1e3).toFixed(1) + " kpx/s";
  return pixelsPerSecond.toFixed(0) + " px/s";
}

function strategyOf(job) {
  const s = job.stats && job.stats.strategy;
  const name = s ? s.name : job.strategy;
  const width = s ? s.bin_width : job.bin_width;
  if (name === "brute") return "brute";
  if (width === 0) return `${name}, surveying for n`;  // auto's survey has not chosen yet
  return name === "exact" ? `exact L=${width}` : `${name} n=${width}`;
}

function timeOf(iso) {
  return iso ? iso.slice(11, 19) : "–";
}

const FINAL_STATES = ["completed", "failed", "canceled"];

// --- API token -------------------------------------------------------------------------

function showSignIn(needed, message) {
  $("sign-in").hidden = !needed;
  $("sign-in-message").textContent = message || "";
  $("sign-out").hidden = needed || !storedToken();
  $("token-button").hidden = !$("sign-in").hidden || Boolean(storedToken());
}

function signIn(token, remember) {
  storeToken(token, remember);
  showSignIn(false);
  refreshSoon();
  retryEventsNow();
}

function signOut() {
  forgetToken();
  location.reload();  // forget every job, frame and image already shown
}

// "#token=T" (a link handed out with the dashboard's address) signs in for this tab, and
// leaves the address at once: the fragment never reaches the server.
function takeTokenFromHash() {
  const match = /(?:^#|&)token=([^&]+)/.exec(location.hash);
  if (!match) return;
  signIn(decodeURIComponent(match[1]), false);
  const rest = location.hash.replace(/(^#|&)token=[^&]+/, "$1").replace(/^#&/, "#");
  history.replaceState(null, "", rest === "#" ? location.pathname : location.pathname + rest);
}

// "#job=7" selects job 7; "#job=7&frame=12" also shows its frame 12 instead of the latest.
function selectedFromHash() {
  const match = /job=(\d+)/.exec(location.hash);
  return match ? Number(match[1]) : null;
}

function frameFromHash() {
  const match = /frame=(\d+)/.exec(location.hash);
  return match ? Number(match[1]) : null;
}

// --- charts ---------------------------------------------------------------------------

const COLORS = {
  blue: "#2f6fdb", orange: "#e0771b", green: "#2a9d55", red: "#d1373f", grey: "#8a8f98",
};

function makeChart(id, config) {
  const canvas = $(id).querySelector("canvas");
  config.options = Object.assign({
    animation: false,
    responsive: true,
    maintainAspectRatio: false,
    parsing: true,
    plugins: { legend: { position: "bottom", labels: { boxWidth: 12 } } },
  }, config.options || {});
  state.charts[id] = new Chart(canvas, config);
  return state.charts[id];
}

function initCharts() {
  makeChart("chart-traced", {
    type: "line",
    data: { datasets: [{ label: "traced pixels / frame pixels", data: [], borderColor: COLORS.blue,
                         backgroundColor: COLORS.blue, pointRadius: 1.5, borderWidth: 1.5, stepped: false }] },
    options: { scales: { x: { type: "linear", title: { display: true, text: "frame" } },
                         y: { min: 0, max: 1, title: { display: true, text: "traced ratio" } } } },
  });
  makeChart("chart-coherence", {
    type: "line",
    data: { datasets: [
      { label: "frame-to-frame", data: [], borderColor: COLORS.blue, backgroundColor: COLORS.blue,
        pointRadius: 1, borderWidth: 1.5 },
      { label: "long-term (since the first frame)", data: [], borderColor: COLORS.orange,
        backgroundColor: COLORS.orange, pointRadius: 1, borderWidth: 1.5 },
    ] },
    options: { scales: { x: { type: "linear", title: { display: true, text: "frame" } },
                         y: { title: { display: true, text: "unchanged share" } } } },
  });
  makeChart("chart-cost", {
    type: "scatter",
    data: { datasets: [
      { label: "predicted by equation 3 (this sequence's d)", data: [], showLine: true,
        borderColor: COLORS.grey, backgroundColor: COLORS.grey, pointRadius: 1.5, borderWidth: 1.5 },
      { label: "predicted, this job", data: [], borderColor: COLORS.blue, backgroundColor: COLORS.blue,
        pointRadius: 6, pointStyle: "rectRot" },
      { label: "measured, this job", data: [], borderColor: COLORS.red, backgroundColor: COLORS.red,
        pointRadius: 6 },
      { label: "auto's survey: predicted traced share", data: [], showLine: true,
        borderColor: COLORS.orange, backgroundColor: COLORS.orange, pointRadius: 2, borderWidth: 1.5,
        borderDash: [5, 4] },
    ] },
    options: { scales: { x: { type: "linear", title: { display: true, text: "bin width n" } },
                         y: { min: 0, title: { display: true, text: "relative cost" } } } },
  });
  makeChart("chart-error", {
    type: "scatter",
    data: { datasets: [
      { label: "spot-check estimate, all jobs", data: [], borderColor: COLORS.grey,
        backgroundColor: COLORS.grey, pointRadius: 4 },
      { label: "this job: estimate and 95 % interval", data: [], showLine: true, borderColor: COLORS.blue,
        backgroundColor: COLORS.blue, pointRadius: [3, 6, 3], borderWidth: 2 },
      { label: "this job: reference pixels differing", data: [], borderColor: COLORS.red,
        backgroundColor: COLORS.red, pointRadius: 6, pointStyle: "triangle" },
    ] },
    options: { scales: { x: { type: "linear", min: 0, title: { display: true, text: "trace seconds" } },
                         y: { min: 0, title: { display: true, text: "error %" } } } },
  });
}

// Sets the datasets' points, redraws, and records how many points were drawn.
function setChartData(id, datasets) {
  const chart = state.charts[id];
  const counts = datasets.map((data, i) => {
    chart.data.datasets[i].data = data;
    return data.filter((p) => p && p.y !== null && p.y !== undefined).length;
  });
  chart.update("none");
  // Points drawn, in all and per dataset: what a test of the page can read back.
  $(id).setAttribute("data-points", String(counts.reduce((a, b) => a + b, 0)));
  $(id).setAttribute("data-points-by-dataset", counts.join(","));
}

// --- jobs -----------------------------------------------------------------------------

function listQuery() {
  const query = new URLSearchParams({ limit: String(state.limit), offset: String(state.offset) });
  for (const [key, value] of Object.entries(state.filters)) if (value) query.set(key, value);
  return query.toString();
}

function renderJobs(page) {
  const jobs = page.jobs;
  state.jobs = jobs;
  // A farm without paging answers only "jobs": then this page is all there is.
  state.total = typeof page.total === "number" ? page.total : state.offset + jobs.length;
  const body = $("jobs").querySelector("tbody");
  body.replaceChildren();
  const filtered = Object.values(state.filters).some(Boolean);
  $("no-jobs").hidden = jobs.length > 0;
  $("no-jobs").textContent = filtered ? "No job matches these filters." : "No jobs yet: submit one above, or with tcfarm submit SCENE.";
  for (const job of jobs) {
    const progress = Math.round((job.progress || 0) * 100);
    const bar = el("div", { class: "bar" }, [el("div", { class: "fill", style: `width:${progress}%` })]);
    const row = el("tr", { "data-job-id": job.id, class: job.id === state.jobId ? "selected" : "" }, [
      el("td", { text: job.id }),
      el("td", { class: "name-col", text: job.name || "" }),
      el("td", {}, [el("span", { class: `state ${job.state}`, text: job.state })]),
      el("td", { class: "progress-col" }, [bar, el("span", { class: "pct", text: `${progress} %` })]),
      el("td", { class: "wide", text: `${job.frames.done}/${job.frames.count}` }),
      el("td", { class: "wide", text: job.frames.done ? fixed(job.traced_pixel_ratio, 4) : "–" }),
      el("td", { class: "wide", text: strategyOf(job) }),
      el("td", { class: "wide", text: String(job.priority) }),
      el("td", { class: "wide", text: seconds(job.stats && job.stats.wall_seconds) }),
    ]);
    row.addEventListener("click", () => { location.hash = `job=${job.id}`; });
    body.appendChild(row);
  }
  const first = jobs.length ? state.offset + 1 : 0;
  const last = state.offset + jobs.length;
  $("page-note").textContent = jobs.length ? `showing ${first}–${last} of ${state.total}` : "";
  $("jobs-count").textContent = `${state.total} ${filtered ? "matching" : "in all"}`;
  $("page-prev").disabled = state.offset === 0;
  $("page-next").disabled = last >= state.total;
}

function latestFinishedFrame(job) {
  const traced = job.traced_per_frame || [];
  for (let i = traced.length - 1; i >= 0; --i) {
    if (traced[i] >= 0) return job.frames.start + i;
  }
  return null;
}

function renderSummary(job) {
  const stats = job.stats || {};
  const parts = [
    ["state", job.state],
    ["size", `${job.width}×${job.height}`],
    ["frames", `${job.frames.done}/${job.frames.count} (${job.frames.start}–${job.frames.end})`],
    ["strategy", strategyOf(job)],
    ["priority", job.priority],
    ["traced ratio", job.frames.done ? fixed(job.traced_pixel_ratio, 4) : "not measured yet"],
    ["wall", seconds(stats.wall_seconds)],
    ["trace", seconds(stats.trace_seconds)],
  ];
  if (stats.trace_cpu_seconds !== undefined) parts.push(["trace CPU", seconds(stats.trace_cpu_seconds)]);
  const cost = stats.cost || {};
  const strategy = stats.strategy || {};
  if (cost.d !== undefined) parts.push(["d", fixed(cost.d, 4)]);
  // The job's one prediction is its plan's; the measured cost counts all its tracing.
  if (typeof strategy.predicted_relative_cost === "number") parts.push(["predicted cost", fixed(strategy.predicted_relative_cost, 3)]);
  if (cost.measured_relative_cost !== undefined) parts.push(["measured cost", fixed(cost.measured_relative_cost, 3)]);
  if (strategy.candidates) parts.push(["auto weighed", strategy.candidates.map(candidateText).join(", ")]);
  if (strategy.reason) parts.push(["why", strategy.reason]);
  if (job.error) parts.push(["error", job.error]);
  $("job-summary").replaceChildren(...parts.map(([key, value]) =>
    el("span", { class: "item" }, [el("b", { text: key + " " }), el("span", { text: String(value) })])));
}

// "exact 1.239 (scene)": a strategy auto weighed, its predicted relative CPU cost and its source.
function candidateText(candidate) {
  const figure = typeof candidate.predicted_relative_cost === "number" ? fixed(candidate.predicted_relative_cost, 3) : "unknown yet";
  return `${candidate.strategy} ${figure} (${candidate.from})`;
}

// What importing the scene added or left out (a default camera, an extension not
// implemented): each warning's message, with its code and where in the file it points.
function renderWarnings(job) {
  const warnings = job.warnings || [];
  const list = $("job-warnings");
  list.hidden = warnings.length === 0;
  list.replaceChildren(...warnings.map(warningItem));
}

function warningItem(warning) {
  if (typeof warning === "string") return el("li", { text: warning });  // recorded before warnings had codes
  return el("li", {}, [
    el("b", { text: `${warning.code} ` }),
    el("span", { text: `${warning.pointer ? `at ${warning.pointer}: ` : ""}${warning.message}` }),
  ]);
}

function renderTracedChart(job) {
  const pixels = job.width * job.height;
  const data = (job.traced_per_frame || []).map((count, i) =>
    ({ x: job.frames.start + i, y: count >= 0 ? count / pixels : null }));
  setChartData("chart-traced", [data]);
}

function renderCoherenceChart(job) {
  const stats = job.stats || {};
  const analysis = stats.analysis;
  const start = job.frames.start;
  if (analysis && analysis.frame_to_frame && analysis.frame_to_frame.by_frame) {
    // by_frame[i] compares frame start + i + 1 with the one before (f2f) / with the first (long-term).
    const f2f = analysis.frame_to_frame.by_frame.map((y, i) => ({ x: start + i + 1, y }));
    const longTerm = (analysis.long_term.by_frame || []).map((y, i) => ({ x: start + i + 1, y }));
    $("coherence-note").textContent =
      `mean frame-to-frame ${fixed(analysis.frame_to_frame.mean, 4)}, long-term ${fixed(analysis.long_term.mean, 4)}`;
    setChartData("chart-coherence", [f2f, longTerm]);
    return;
  }
  const coherence = stats.coherence;
  if (!coherence) {
    $("coherence-note").textContent = "(no frames yet)";
    setChartData("chart-coherence", [[], []]);
    return;
  }
  // Running: the means over the frames done so far, drawn across them.
  const last = latestFinishedFrame(job);
  const end = last === null ? start + 1 : Math.max(last, start + 1);
  const flat = (y) => [{ x: start + 1, y }, { x: end, y }];
  $("coherence-note").textContent = "(running means; by frame when the job completes)";
  setChartData("chart-coherence", [flat(coherence.frame_to_frame.mean), flat(coherence.long_term.mean)]);
}

function renderCostChart(job) {
  const stats = job.stats || {};
  const cost = stats.cost || {};
  const width = stats.strategy ? stats.strategy.bin_width : job.bin_width;
  const predictions = (stats.analysis && stats.analysis.predictions) || [];
  const curve = predictions.map((p) => ({ x: p.bin_width, y: p.relative_cost }));
  const prediction = stats.strategy ? stats.strategy.predicted_relative_cost : undefined;
  const predicted = typeof prediction === "number" ? [{ x: width, y: prediction }] : [];
  const measured = cost.measured_relative_cost !== undefined ? [{ x: width, y: cost.measured_relative_cost }] : [];
  // auto's guarded jobs: what its survey predicted for each width it weighed.
  const survey = (stats.strategy && stats.strategy.survey) || {};
  const surveyed = Object.entries(survey.predicted_traced_share || {})
    .map(([n, share]) => ({ x: Number(n), y: share }))
    .sort((a, b) => a.x - b.x);
  setChartData("chart-cost", [curve, predicted, measured, surveyed]);
}

// The error figures that have been measured: spot checks once a copied pixel was traced
// again, the comparison with brute force once a reference frame was compared. Before that
// a figure is not a result (a 0/0 check has a 0–51 % interval; SSIM starts at 1).
function errorFigures(job) {
  const error = (job.stats && job.stats.error) || {};
  const spot = error.spot_checks && error.spot_checks.pixels_checked > 0 ? error.spot_checks : null;
  const reference = error.reference && error.reference.frames_compared > 0 ? error.reference : null;
  return { spot, reference, asked: error.reference, suspect: error.suspect };
}

function errorNotes(job) {
  const { spot, reference, asked, suspect } = errorFigures(job);
  const notes = [];
  if (spot) {
    const ci = spot.ci95_percent || [spot.estimated_error_percent, spot.estimated_error_percent];
    notes.push(`spot checks: ${fixed(spot.estimated_error_percent, 4)} % of pixels wrong ` +
               `(95 % CI ${fixed(ci[0], 4)}–${fixed(ci[1], 4)} %, ${spot.mismatches}/${spot.pixels_checked} checked)`);
  } else if (FINAL_STATES.includes(job.state)) {
    notes.push("spot checks: none made (a frame compared with brute force, or with nothing copied, needs none)");
  } else {
    notes.push("spot checks: not measured yet");
  }
  if (reference) {
    // No PSNR (null, or left out) is an infinite one: the frames are identical.
    const psnr = reference.psnr_db === null || reference.psnr_db === undefined ? "∞ dB (identical)" : `${fixed(reference.psnr_db, 1)} dB`;
    notes.push(`against brute force (${reference.frames_compared}/${reference.frames_requested} frames): ` +
               `${fixed(reference.percent_differing, 4)} % differ, max error ${fixed(reference.max_abs_error, 4)}, ` +
               `PSNR ${psnr}, SSIM ${fixed(reference.ssim, 4)}`);
  } else if (asked) {
    notes.push(`against brute force: not measured yet (0/${asked.frames_requested} frames compared)`);
  }
  const sample = ((job.stats && job.stats.error) || {}).referee_sample;
  if (sample) notes.push(refereeSampleNote(sample));
  if (suspect) notes.push(`SUSPECT: ${suspect.pixels_disagreeing} pixels disagree: ${suspect.why || ""}`);
  return notes;
}

// The referee's unseen sample: what it traced, what it found, and what that buys: the
// chance that a worker altering 16 of the pixels it sends each frame is caught.
function refereeSampleNote(sample) {
  const share = `${fixed(100 * sample.share, 2)} % of every worker's pixels`;
  if (!sample.referee_traces) return `referee's unseen sample: none traced yet (it traces ${share})`;
  const catchAll = sample.catch_probability ? sample.catch_probability.altering_16_pixels_every_frame : 0;
  const missed = 1 - catchAll;
  const odds = missed > 0 ? `1 in ${Math.round(1 / missed).toLocaleString("en")} missed` : "none missed";
  return `referee's unseen sample: ${share} ` +
         `(${sample.pixels_sampled} px drawn, ${sample.referee_traces} traced with their horizons, ` +
         `${sample.pixels_wrong} wrong, ` +
         `${fixed(sample.referee_cpu_seconds, 2)} s referee CPU); a worker altering 16 px a frame: ${odds}`;
}

function renderErrorChart(job) {
  const all = [];
  for (const other of state.jobs) {
    const { spot } = errorFigures(other);
    if (other.id !== job.id && spot && other.stats) {
      all.push({ x: other.stats.trace_seconds, y: spot.estimated_error_percent });
    }
  }
  const { spot, reference } = errorFigures(job);
  const x = job.stats && job.stats.trace_seconds ? job.stats.trace_seconds : 0;
  const interval = [];
  if (spot) {
    const ci = spot.ci95_percent || [spot.estimated_error_percent, spot.estimated_error_percent];
    interval.push({ x, y: ci[0] }, { x, y: spot.estimated_error_percent }, { x, y: ci[1] });
  }
  const referencePoints = reference ? [{ x, y: reference.percent_differing }] : [];
  const notes = errorNotes(job);
  $("error-note").replaceChildren(...notes.map((note) => el("div", { text: note })));
  $("chart-error").dataset.measured = spot || reference ? "1" : "0";
  setChartData("chart-error", [all, interval, referencePoints]);
}

// --- frame images ---------------------------------------------------------------------
//
// Each image is fetched off-screen and shown once it decoded, so what is on screen is always
// a whole image. A frame just finished may not be written yet, nor its masks (the frame
// writer runs behind the planner; a change mask waits for the frame before): a failed fetch
// keeps the last image, says so in the caption, and tries again after a growing pause.

const IMAGE_RETRY_MS = [250, 500, 1000, 2000, 4000];
const IMAGE_ATTEMPTS = 40;  // about two and a half minutes: then the frame is not coming
const loaders = {};

function setImage(id, url, frame, what) {
  const img = $(id);
  if (img.dataset.src === url) return;
  if (loaders[id] && loaders[id].url === url) return;  // loading, or waiting to try again
  const current = { url, attempt: 0, timer: null };
  loaders[id] = current;
  const mine = () => loaders[id] === current;
  const attempt = () => {
    current.timer = null;
    apiFetch(url + "?t=" + Date.now())  // with the token: an <img> cannot send a header
      .then((response) => response.blob())
      .then((blob) => {
        const objectUrl = URL.createObjectURL(blob);
        const loader = new Image();
        loader.onload = () => {
          if (!mine()) {
            URL.revokeObjectURL(objectUrl);
            return;
          }
          delete loaders[id];
          if (img.src.startsWith("blob:")) URL.revokeObjectURL(img.src);
          img.dataset.src = url;
          img.dataset.frame = String(frame);
          img.src = objectUrl;
          $(`${id}-caption`).textContent = `(frame ${frame})`;
        };
        loader.onerror = () => {
          URL.revokeObjectURL(objectUrl);
          retry("could not be decoded");
        };
        loader.src = objectUrl;
      })
      .catch((error) => retry(error.status === 0 ? "the farm is unreachable" : "not written yet"));
  };
  const retry = (why) => {
    if (!mine()) return;
    if (current.attempt >= IMAGE_ATTEMPTS) {
      $(`${id}-caption`).textContent = `(${what} of frame ${frame} is not available: ${why})`;
      return;  // kept in loaders, so the same image is not asked for again
    }
    const pause = IMAGE_RETRY_MS[Math.min(current.attempt, IMAGE_RETRY_MS.length - 1)];
    current.attempt += 1;
    img.dataset.retries = String(current.attempt);
    const shown = img.dataset.frame ? ` showing frame ${img.dataset.frame}` : "";
    $(`${id}-caption`).textContent = `(${what} of frame ${frame} ${why}: trying again${shown ? ";" + shown : ""})`;
    current.timer = setTimeout(attempt, pause);
  };
  attempt();
}

function clearImages() {
  for (const id of ["frame-image", "mask-image", "change-image"]) {
    const img = $(id);
    if (loaders[id] && loaders[id].timer) clearTimeout(loaders[id].timer);
    delete loaders[id];
    img.dataset.loaded = "0";
    delete img.dataset.src;
    delete img.dataset.frame;
    delete img.dataset.retries;
    img.removeAttribute("src");
    $(`${id}-caption`).textContent = "";
  }
}

function renderImages(job) {
  const slider = $("frame-slider");
  slider.min = job.frames.start;
  slider.max = job.frames.end;
  const latest = latestFinishedFrame(job);
  if (state.follow || state.frame === null) state.frame = latest;
  if (state.frame === null) {
    $("frame-number").textContent = "– (none finished yet)";
    return;
  }
  slider.value = state.frame;
  const traced = (job.traced_per_frame || [])[state.frame - job.frames.start];
  $("frame-number").textContent = traced >= 0
    ? `${state.frame} (${fixed(traced / (job.width * job.height), 4)} traced)`
    : `${state.frame} (not finished)`;
  const base = `${API}/jobs/${job.id}/frames/${state.frame}`;
  setImage("frame-image", `${base}.png`, state.frame, "the image");
  setImage("mask-image", `${base}/mask.png`, state.frame, "the traced mask");
  setImage("change-image", `${base}/change.png`, state.frame, "the change mask");
}

function showFrame(frame) {
  state.frame = frame;
  state.follow = false;
  $("frame-follow").checked = false;
  if (state.job) renderImages(state.job);
}

// --- per-frame state ------------------------------------------------------------------

const FRAME_STATES = ["written", "tracing", "queued", "failed"];

// One cell a frame, coloured by its state; a click shows that frame. From GET
// /jobs/{id}/frames, or, from a farm without it, from traced_per_frame (written or not).
function renderFrameStrip(job, states) {
  const frames = states ? states.frames : (job.traced_per_frame || []).map((traced, i) => ({
    frame: job.frames.start + i, state: traced >= 0 ? "written" : "queued", traced: traced >= 0 ? traced : null,
  }));
  const counts = {};
  const cells = frames.map((f) => {
    counts[f.state] = (counts[f.state] || 0) + 1;
    const figures = [f.traced !== null && f.traced !== undefined ? `${f.traced} traced` : "",
                     f.copied !== null && f.copied !== undefined ? `${f.copied} copied` : ""].filter(Boolean);
    const cell = el("span", {
      class: `cell ${f.state}${f.frame === state.frame ? " current" : ""}`, "data-frame": f.frame,
      "data-state": f.state, title: `frame ${f.frame}: ${f.state}${figures.length ? ", " + figures.join(", ") : ""}`,
    });
    cell.addEventListener("click", () => showFrame(f.frame));
    return cell;
  });
  $("frame-strip").replaceChildren(...cells);
  $("frame-strip-note").textContent = FRAME_STATES.filter((s) => counts[s])
    .map((s) => `${counts[s]} ${s}`).join(", ");
}

// --- events ---------------------------------------------------------------------------

function eventText(event) {
  const extra = Object.entries(event)
    .filter(([key]) => !["seq", "job", "time", "type", "message"].includes(key))
    .map(([key, value]) => `${key} ${typeof value === "object" ? JSON.stringify(value) : value}`);
  return (event.message || "") + (extra.length && !event.message ? extra.join(", ") : "");
}

function renderEvents() {
  const shown = state.events.slice(-EVENTS_SHOWN).reverse();  // newest first
  $("events").replaceChildren(...shown.map((event) => el("li", {
    "data-seq": event.seq, "data-type": event.type, "data-via": event.via || "list", class: `event ${event.type}`,
  }, [
    el("time", { text: timeOf(event.time), title: event.time || "" }),
    el("span", { class: "type", text: event.type }),
    el("span", { class: "message", text: eventText(event) }),
  ])));
  $("events-note").textContent = !state.hasEvents ? "(this farm keeps no events)"
    : state.events.length > EVENTS_SHOWN ? `(the latest ${EVENTS_SHOWN} of ${state.events.length})` : "";
}

function addEvents(events, via) {
  const known = new Set(state.events.map((event) => event.seq));
  let added = false;
  for (const event of events) {
    if (known.has(event.seq)) continue;
    state.events.push(Object.assign({ via }, event));
    known.add(event.seq);
    added = true;
  }
  if (!added) return;
  state.events.sort((a, b) => a.seq - b.seq);
  renderEvents();
}

async function loadEvents(jobId) {
  try {
    const { events } = await getJson(`${API}/jobs/${jobId}/events`);
    if (jobId !== state.jobId) return;
    state.hasEvents = true;
    addEvents(events, "list");
  } catch (error) {
    // A farm without events answers not_found (no such route); a deleted job, job_not_found.
    if (error.code !== "not_found" && error.status !== 405) throw error;
    state.hasEvents = false;
    renderEvents();
  }
}

// --- actions --------------------------------------------------------------------------

function actionMessage(text, kind) {
  const node = $("action-message");
  node.textContent = text;
  node.dataset.kind = kind || "";
}

function bytesText(bytes) {
  return typeof bytes === "number" ? `${sizeText(bytes)} (${bytes.toLocaleString("en")} bytes)` : "";
}

// Runs an action on the selected job; says what happened, or what the farm refused and why.
async function act(what, run) {
  const id = state.jobId;
  actionMessage(`${what} job ${id}…`, "busy");
  try {
    const said = await run(id);
    actionMessage(said, "ok");
  } catch (error) {
    actionMessage(`Could not ${what} job ${id}: ${error.plain || error.message}`, "error");
  }
  refreshSoon();
}

function renderActions(job) {
  const active = !FINAL_STATES.includes(job.state);
  $("action-cancel").disabled = !active;
  $("action-retry").disabled = job.state !== "failed" && job.state !== "canceled";
  $("action-delete").disabled = active;
  $("action-delete").title = active ? "cancel it first: a queued or running job cannot be deleted" : "";
  const input = $("action-priority-value");
  if (document.activeElement !== input && input.dataset.job !== String(job.id) + ":" + job.priority) {
    input.value = job.priority;
    input.dataset.job = String(job.id) + ":" + job.priority;
  }
}

function initActions() {
  $("action-cancel").addEventListener("click", () => act("cancel", async (id) => {
    await sendJson("POST", `${API}/jobs/${id}/cancel`);
    return `Canceled job ${id}.`;
  }));
  $("action-retry").addEventListener("click", () => act("retry", async (id) => {
    await sendJson("POST", `${API}/jobs/${id}/retry`);
    return `Job ${id} is queued again.`;
  }));
  $("action-priority").addEventListener("click", () => act("change the priority of", async (id) => {
    const value = $("action-priority-value").value.trim();
    const priority = Number(value);
    if (value === "" || !Number.isInteger(priority)) throw new Error(`"${value}" is not a whole number from −100 to 100`);
    const job = await sendJson("PATCH", `${API}/jobs/${id}`, { priority });
    return `Job ${id} now has priority ${job.priority}.`;
  }));
  $("action-delete").addEventListener("click", () => {
    const job = state.job;
    if (!job) return;
    $("delete-question").textContent = `Delete job ${job.id} “${job.name}” (${job.state}, ${job.frames.done} frames written), ` +
      "its frames and the assets no other job uses? This cannot be undone.";
    $("delete-confirm").hidden = false;
    $("delete-confirm").dataset.job = String(job.id);
    $("delete-no").focus();
  });
  $("delete-no").addEventListener("click", () => { $("delete-confirm").hidden = true; });
  $("delete-yes").addEventListener("click", () => {
    $("delete-confirm").hidden = true;
    act("delete", async (id) => {
      const deleted = await sendJson("DELETE", `${API}/jobs/${id}`);
      if (state.jobId === id) {
        history.replaceState(null, "", location.pathname);
        state.autoSelect = false;
        selectJob(null);
      }
      return `Deleted job ${id}; freed ${bytesText(deleted.freed_bytes)}.`;
    });
  });
}

function renderJob(job) {
  $("job-detail").hidden = false;
  $("job-title").textContent = `Job ${job.id}: ${job.name || ""}`;
  renderActions(job);
  renderSummary(job);
  renderWarnings(job);
  renderImages(job);
  renderTracedChart(job);
  renderCoherenceChart(job);
  renderCostChart(job);
  renderErrorChart(job);
}

// --- workers --------------------------------------------------------------------------

function renderWorkers(farm) {
  const body = $("workers").querySelector("tbody");
  body.replaceChildren();
  const workers = farm.workers || [];
  $("no-workers").hidden = workers.length > 0;
  $("queue-note").textContent = `${farm.queued_tasks || 0} tasks queued, ${farm.in_flight_tasks || 0} in flight`;
  for (const w of workers) {
    const heard = w.seconds_since_heard;
    body.appendChild(el("tr", { "data-worker": w.name, class: heard > 5 ? "stale" : "" }, [
      el("td", { class: "name-col", text: w.name }),
      el("td", { class: "wide", text: w.threads }),
      el("td", { class: "wide", text: w.capacity }),
      el("td", { text: w.in_flight }),
      el("td", { class: "wide", text: w.tasks_done }),
      el("td", { class: "wide", text: (w.pixels_done || 0).toLocaleString("en") }),
      el("td", { text: rate(w.trace_seconds > 0 ? w.pixels_done / w.trace_seconds : 0) }),
      el("td", { text: `${fixed(heard, 1)} s ago` }),
    ]));
  }
}

// --- refreshing -----------------------------------------------------------------------

function setConnection(ok, message) {
  const node = $("connection");
  node.dataset.state = ok ? (state.stream === "live" ? "ok" : "polling") : "error";
  node.dataset.stream = state.stream;
  node.textContent = !ok ? message : state.stream === "live" ? "live" : "polling";
  node.title = ok ? (state.stream === "live" ? "following the farm's event stream" : "asking the farm every second")
                  : message;
}

async function refreshJob() {
  const id = state.jobId;
  if (id === null) return;
  let job;
  try {
    job = await getJson(`${API}/jobs/${id}`);
  } catch (error) {
    if (error.status === 404 && id === state.jobId) {  // deleted meanwhile
      actionMessage(`Job ${id} is gone: ${error.plain}`, "error");
      $("job-detail").hidden = true;
      return;
    }
    throw error;
  }
  if (id !== state.jobId) return;
  state.job = job;
  renderJob(job);
  let frames = null;
  try {
    frames = await getJson(`${API}/jobs/${id}/frames`);
  } catch (error) {
    if (error.status !== 404 && error.status !== 405) throw error;  // a farm without it
  }
  if (id === state.jobId) renderFrameStrip(job, frames);
  if (state.stream !== "live") await loadEvents(id);
}

// Every <select data-strategies> offers the coordinator's own strategies (GET
// /api/v1/strategies), once per page: a select marked data-default names the farm's default
// in its empty option.
let strategiesShown = false;
async function showStrategies() {
  const listed = await getJson(`${API}/strategies`);
  for (const select of document.querySelectorAll("select[data-strategies]")) {
    select.append(...listed.strategies.map((name) => el("option", { value: name, text: name })));
    const fallback = select.querySelector("option[data-default]");
    if (fallback) fallback.textContent = `the farm's default (${listed.default})`;
  }
  strategiesShown = true;
}

async function refresh() {
  if (!strategiesShown) await showStrategies();
  const query = listQuery();
  const [page, farm] = await Promise.all([getJson(`${API}/jobs?${query}`), getJson(`${API}/workers`)]);
  // Filters or the page changed meanwhile: this answer is of a list no longer asked for,
  // and the refresh they asked for comes next.
  if (query === listQuery()) {
    if (state.jobId === null && state.autoSelect && page.jobs.length && state.offset === 0 &&
        !Object.values(state.filters).some(Boolean)) {
      selectJob(page.jobs[0].id);
    }
    renderJobs(page);
  }
  renderWorkers(farm);
  await refreshJob();
}

let refreshTimer = null;
let refreshAt = Infinity;   // when refreshTimer fires
let refreshing = false;
let refreshWanted = false;  // asked for while one ran: another follows it at once

// A refresh after `delay` ms, unless one is due sooner; the page then polls on its own.
function refreshSoon(delay = 0) {
  const at = Date.now() + delay;
  if (refreshTimer !== null && at >= refreshAt) return;
  clearTimeout(refreshTimer);
  refreshAt = at;
  refreshTimer = setTimeout(() => {
    refreshTimer = null;
    refreshAt = Infinity;
    runRefresh();
  }, delay);
}

async function runRefresh() {
  if (refreshing) {
    refreshWanted = true;
    return;
  }
  refreshing = true;
  try {
    await refresh();
    setConnection(true);
  } catch (error) {
    setConnection(false, error.plain || String(error.message || error));
  } finally {
    refreshing = false;
    if (refreshWanted) {
      refreshWanted = false;
      refreshSoon(0);
    } else {
      refreshSoon(state.stream === "live" ? LIVE_POLL_MS : POLL_MS);
    }
  }
}

function onFarmEvent(event) {
  if (event.job === state.jobId) addEvents([event], "stream");
  refreshSoon(REFRESH_DELAY_MS);
}

function onStreamState(stream, detail) {
  const was = state.stream;
  state.stream = stream;
  const node = $("connection");
  node.dataset.stream = stream;
  node.dataset.streamDetail = detail || "";
  if (stream === "live" && was !== "live") {
    // Back: fetch what changed while the stream was down (the events too), and say so.
    if (state.jobId !== null) loadEvents(state.jobId).catch(() => {});
    refreshSoon();
  } else if (node.dataset.state !== "error") {
    setConnection(true);
  }
}

function selectJob(id) {
  if (id === state.jobId) return;
  state.jobId = id;
  state.job = null;
  state.frame = null;
  state.follow = true;
  state.events = [];
  $("frame-follow").checked = true;
  $("delete-confirm").hidden = true;
  $("frame-strip").replaceChildren();
  renderEvents();
  clearImages();
  if (id === null) {
    $("job-detail").hidden = true;
    return;
  }
  loadEvents(id).catch(() => {});
}

function initFilters() {
  let typing = null;
  // Reads every filter at once; only a change of them goes back to the first page.
  const apply = () => {
    clearTimeout(typing);
    const filters = { state: $("filter-state").value, strategy: $("filter-strategy").value, name: $("filter-name").value.trim() };
    if (JSON.stringify(filters) === JSON.stringify(state.filters)) return;
    state.filters = filters;
    state.offset = 0;
    refreshSoon();
  };
  $("filter-state").addEventListener("change", apply);
  $("filter-strategy").addEventListener("change", apply);
  $("filter-name").addEventListener("input", () => {
    clearTimeout(typing);
    typing = setTimeout(apply, 250);
  });
  $("page-prev").addEventListener("click", () => {
    state.offset = Math.max(0, state.offset - state.limit);
    refreshSoon();
  });
  $("page-next").addEventListener("click", () => {
    state.offset += state.limit;
    refreshSoon();
  });
}

function init() {
  onUnauthorized = (message) => showSignIn(true, message);
  takeTokenFromHash();
  showSignIn(false);
  $("sign-in").addEventListener("submit", (event) => {
    event.preventDefault();
    signIn($("token-input").value, $("token-remember").checked);
    $("token-input").value = "";
  });
  $("token-button").addEventListener("click", () => showSignIn(true, "A token of the farm's --api-tokens file."));
  $("sign-out").addEventListener("click", signOut);
  initCharts();
  initActions();
  initFilters();
  initSubmitForm();
  for (const id of ["frame-image", "mask-image", "change-image"]) {
    const img = $(id);
    img.addEventListener("load", () => { img.dataset.loaded = "1"; });
    img.addEventListener("error", () => { img.dataset.loaded = "0"; });
  }
  $("frame-slider").addEventListener("input", (event) => showFrame(Number(event.target.value)));
  $("frame-follow").addEventListener("change", (event) => {
    state.follow = event.target.checked;
    if (state.job) renderImages(state.job);
  });
  const applyFrameFromHash = () => {
    if (frameFromHash() !== null) showFrame(frameFromHash());
  };
  window.addEventListener("hashchange", () => {
    if (selectedFromHash() !== state.jobId) actionMessage("");  // it spoke of another job
    selectJob(selectedFromHash());
    applyFrameFromHash();
    refreshSoon();
  });
  selectJob(selectedFromHash());
  applyFrameFromHash();
  refreshSoon();
  followEvents({ onEvent: onFarmEvent, onState: onStreamState });
}

init();
