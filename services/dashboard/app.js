// tcfarm dashboard: polls the coordinator's HTTP API (proto/openapi.yaml) every second
// and draws the jobs, the selected job's coherence figures and the workers. Charts are
// Chart.js (node_modules/chart.js, installed from npm by scripts/bootstrap).
//
// A farm with API tokens answers 401: the page then asks for a token, keeps it in this
// tab's sessionStorage and sends it as "Authorization: Bearer" on every request, images
// included (fetched, then shown from blob URLs), never in a URL the server sees.
"use strict";

const POLL_MS = 1000;
const API = "api/v1";

const state = {
  jobId: null,          // the selected job
  job: null,            // its last record
  jobs: [],             // the last job list
  frame: null,          // the frame the images show
  follow: true,         // the images follow the latest finished frame
  charts: {},
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

// --- API token -------------------------------------------------------------------------

const TOKEN_KEY = "tcfarm-api-token";

function storedToken() { return sessionStorage.getItem(TOKEN_KEY); }

function showSignIn(needed, message) {
  $("sign-in").hidden = !needed;
  $("sign-in-message").textContent = message || "";
  $("sign-out").hidden = needed || !storedToken();
}

function signIn(token) {
  sessionStorage.setItem(TOKEN_KEY, token.trim());
  showSignIn(false);
}

function signOut() {
  sessionStorage.removeItem(TOKEN_KEY);
  location.reload();  // forget every job, frame and image already shown
}

// "#token=T" (a link handed out with the dashboard's address) signs in once, and leaves
// the address at once: the fragment never reaches the server.
function takeTokenFromHash() {
  const match = /(?:^#|&)token=([^&]+)/.exec(location.hash);
  if (!match) return;
  signIn(decodeURIComponent(match[1]));
  const rest = location.hash.replace(/(^#|&)token=[^&]+/, "$1").replace(/^#&/, "#");
  history.replaceState(null, "", rest === "#" ? location.pathname : location.pathname + rest);
}

async function apiFetch(path) {
  const headers = storedToken() ? { Authorization: `Bearer ${storedToken()}` } : {};
  const response = await fetch(path, { cache: "no-store", headers });
  if (response.status === 401) {
    showSignIn(true, storedToken() ? "The farm does not know this token." : "This farm needs an API token.");
    throw new Error("sign in: the farm needs an API token");
  }
  if (response.status === 403) throw new Error(`${path}: this token's role may not read it`);
  if (!response.ok) throw new Error(`${path}: HTTP ${response.status}`);
  return response;
}

async function getJson(path) {
  return (await apiFetch(path)).json();
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

function renderJobs(jobs) {
  const body = $("jobs").querySelector("tbody");
  body.replaceChildren();
  $("no-jobs").hidden = jobs.length > 0;
  for (const job of jobs) {
    const progress = Math.round((job.progress || 0) * 100);
    const bar = el("div", { class: "bar" }, [el("div", { class: "fill", style: `width:${progress}%` })]);
    const row = el("tr", { "data-job-id": job.id, class: job.id === state.jobId ? "selected" : "" }, [
      el("td", { text: job.id }),
      el("td", { text: job.name || "" }),
      el("td", {}, [el("span", { class: `state ${job.state}`, text: job.state })]),
      el("td", { class: "progress-col" }, [bar, el("span", { class: "pct", text: `${progress} %` })]),
      el("td", { text: `${job.frames.done}/${job.frames.count}` }),
      el("td", { text: fixed(job.traced_pixel_ratio, 4) }),
      el("td", { text: strategyOf(job) }),
      el("td", { text: seconds(job.stats && job.stats.wall_seconds) }),
    ]);
    row.addEventListener("click", () => { location.hash = `job=${job.id}`; });
    body.appendChild(row);
  }
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
    ["traced ratio", fixed(job.traced_pixel_ratio, 4)],
    ["wall", seconds(stats.wall_seconds)],
    ["trace", seconds(stats.trace_seconds)],
  ];
  if (stats.trace_cpu_seconds !== undefined) parts.push(["trace CPU", seconds(stats.trace_cpu_seconds)]);
  const cost = stats.cost || {};
  if (cost.d !== undefined) parts.push(["d", fixed(cost.d, 4)]);
  if (cost.predicted_relative_cost !== undefined) parts.push(["predicted cost", fixed(cost.predicted_relative_cost, 3)]);
  if (cost.measured_relative_cost !== undefined) parts.push(["measured cost", fixed(cost.measured_relative_cost, 3)]);
  if (job.error) parts.push(["error", job.error]);
  $("job-summary").replaceChildren(...parts.map(([key, value]) =>
    el("span", { class: "item" }, [el("b", { text: key + " " }), el("span", { text: String(value) })])));
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
  const predicted = cost.predicted_relative_cost !== undefined ? [{ x: width, y: cost.predicted_relative_cost }] : [];
  const measured = cost.measured_relative_cost !== undefined ? [{ x: width, y: cost.measured_relative_cost }] : [];
  // auto's guarded jobs: what its survey predicted for each width it weighed.
  const survey = (stats.strategy && stats.strategy.survey) || {};
  const surveyed = Object.entries(survey.predicted_traced_share || {})
    .map(([n, share]) => ({ x: Number(n), y: share }))
    .sort((a, b) => a.x - b.x);
  setChartData("chart-cost", [curve, predicted, measured, surveyed]);
}

function errorFigures(job) {
  const error = (job.stats && job.stats.error) || {};
  return { spot: error.spot_checks, reference: error.reference };
}

function renderErrorChart(job) {
  const all = [];
  for (const other of state.jobs) {
    const { spot } = errorFigures(other);
    if (other.id !== job.id && spot && spot.estimated_error_percent !== undefined && other.stats) {
      all.push({ x: other.stats.trace_seconds, y: spot.estimated_error_percent });
    }
  }
  const { spot, reference } = errorFigures(job);
  const x = job.stats ? job.stats.trace_seconds : 0;
  const interval = [];
  const notes = [];
  if (spot && spot.estimated_error_percent !== undefined) {
    const ci = spot.ci95_percent || [spot.estimated_error_percent, spot.estimated_error_percent];
    interval.push({ x, y: ci[0] }, { x, y: spot.estimated_error_percent }, { x, y: ci[1] });
    notes.push(`spot checks: ${fixed(spot.estimated_error_percent, 4)} % of pixels wrong ` +
               `(95 % CI ${fixed(ci[0], 4)}–${fixed(ci[1], 4)} %, ${spot.mismatches}/${spot.pixels_checked} checked)`);
  }
  const referencePoints = [];
  if (reference && reference.percent_differing !== undefined) {
    referencePoints.push({ x, y: reference.percent_differing });
    notes.push(`against brute force: ${fixed(reference.percent_differing, 4)} % differ, ` +
               `PSNR ${fixed(reference.psnr_db, 1)} dB, SSIM ${fixed(reference.ssim, 4)}`);
  }
  $("error-note").textContent = notes.length ? notes.join(" · ") : "no error figures yet";
  setChartData("chart-error", [all, interval, referencePoints]);
}

// --- frame images ---------------------------------------------------------------------

// Each image is fetched off-screen first and shown once it loaded, so a frame that is
// finished but not written yet (the frame writer runs behind the planner; a change mask
// waits for the frame before) keeps the last one on screen, and the next poll tries again.
const loaders = {};

function setImage(id, url, frame) {
  const img = $(id);
  if (img.dataset.src === url) return;
  if (loaders[id] && loaders[id].url === url) return;  // still loading
  const loader = new Image();
  loaders[id] = { url, loader };
  loader.onload = () => {
    if (!loaders[id] || loaders[id].loader !== loader) {
      URL.revokeObjectURL(loader.src);
      return;
    }
    delete loaders[id];
    if (img.src.startsWith("blob:")) URL.revokeObjectURL(img.src);
    img.dataset.src = url;
    img.dataset.frame = String(frame);
    img.src = loader.src;
    $(`${id}-caption`).textContent = `(frame ${frame})`;
  };
  const forget = () => {
    if (loaders[id] && loaders[id].loader === loader) delete loaders[id];
  };
  loader.onerror = forget;
  // Fetched with the token, shown from a blob URL: an <img> cannot send a header.
  apiFetch(url + "?t=" + Date.now())
    .then((response) => response.blob())
    .then((blob) => { loader.src = URL.createObjectURL(blob); })
    .catch(forget);
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
  const traced = job.traced_per_frame[state.frame - job.frames.start];
  $("frame-number").textContent = traced >= 0
    ? `${state.frame} (${fixed(traced / (job.width * job.height), 4)} traced)`
    : `${state.frame} (not finished)`;
  const base = `${API}/jobs/${job.id}/frames/${state.frame}`;
  setImage("frame-image", `${base}.png`, state.frame);
  setImage("mask-image", `${base}/mask.png`, state.frame);
  setImage("change-image", `${base}/change.png`, state.frame);
}

function renderJob(job) {
  $("job-detail").hidden = false;
  $("job-title").textContent = `Job ${job.id}: ${job.name || ""}`;
  renderSummary(job);
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
      el("td", { text: w.name }),
      el("td", { text: w.threads }),
      el("td", { text: w.capacity }),
      el("td", { text: w.in_flight }),
      el("td", { text: w.tasks_done }),
      el("td", { text: (w.pixels_done || 0).toLocaleString("en") }),
      el("td", { text: rate(w.trace_seconds > 0 ? w.pixels_done / w.trace_seconds : 0) }),
      el("td", { text: `${fixed(heard, 1)} s ago` }),
    ]));
  }
}

// --- polling --------------------------------------------------------------------------

function setConnection(ok, message) {
  const node = $("connection");
  node.dataset.state = ok ? "ok" : "error";
  node.textContent = ok ? "live" : message;
}

async function poll() {
  try {
    const [list, farm] = await Promise.all([getJson(`${API}/jobs?limit=100`), getJson(`${API}/workers`)]);
    state.jobs = list.jobs;
    if (state.jobId === null && list.jobs.length) state.jobId = list.jobs[0].id;
    renderJobs(list.jobs);
    renderWorkers(farm);
    if (state.jobId !== null) {
      state.job = await getJson(`${API}/jobs/${state.jobId}`);
      renderJob(state.job);
    }
    setConnection(true);
  } catch (error) {
    setConnection(false, String(error.message || error));
  } finally {
    setTimeout(poll, POLL_MS);
  }
}

function selectJob(id) {
  if (id === state.jobId) return;
  state.jobId = id;
  state.frame = null;
  state.follow = true;
  $("frame-follow").checked = true;
  for (const id of ["frame-image", "mask-image", "change-image"]) {
    const img = $(id);
    delete loaders[id];
    img.dataset.loaded = "0";
    delete img.dataset.src;
    img.removeAttribute("src");
    $(`${id}-caption`).textContent = "";
  }
}

function init() {
  takeTokenFromHash();
  showSignIn(false);
  $("sign-in").addEventListener("submit", (event) => {
    event.preventDefault();
    signIn($("token-input").value);
    $("token-input").value = "";
  });
  $("sign-out").addEventListener("click", signOut);
  initCharts();
  for (const id of ["frame-image", "mask-image", "change-image"]) {
    const img = $(id);
    img.addEventListener("load", () => { img.dataset.loaded = "1"; });
    img.addEventListener("error", () => { img.dataset.loaded = "0"; });
  }
  $("frame-slider").addEventListener("input", (event) => {
    state.frame = Number(event.target.value);
    state.follow = false;
    $("frame-follow").checked = false;
    if (state.job) renderImages(state.job);
  });
  $("frame-follow").addEventListener("change", (event) => {
    state.follow = event.target.checked;
    if (state.job) renderImages(state.job);
  });
  const applyFrameFromHash = () => {
    if (frameFromHash() === null) return;
    state.frame = frameFromHash();
    state.follow = false;
    $("frame-follow").checked = false;
    if (state.job) renderImages(state.job);
  };
  window.addEventListener("hashchange", () => {
    selectJob(selectedFromHash());
    if (state.job && state.job.id !== state.jobId) state.job = null;
    applyFrameFromHash();
  });
  state.jobId = selectedFromHash();
  applyFrameFromHash();
  poll();
}

init();
