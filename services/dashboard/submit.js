// tcfarm dashboard: the submit form. It does what `tcfarm submit` does
// (services/client/tcfarm/scene_files.py and client.py): finds the files a scene references,
// asks the farm whether it would take the scene (POST /api/v1/scenes/check, nothing uploaded
// yet), asks it which files it lacks (POST /api/v1/assets/missing), uploads those by SHA-256
// (PUT /api/v1/assets/{sha256}) and submits the job (POST /api/v1/jobs).
"use strict";

// --- the files a scene references (scene_files.py, the same rules) --------------------

class SceneFileError extends Error {}
// A file that does not read as the format its name says; the farm can say what it is instead.
class NotItsFormat extends SceneFileError {
  constructor(path, message) {
    super(message);
    this.path = path;
  }
}

const SCENE_FILE_TYPES = [".json", ".gltf", ".glb", ".obj"];

// The textures of a material's "pbr" block (glTF's model), as proto/scene.schema.json names them.
const PBR_TEXTURES = ["base_color_texture", "metallic_roughness_texture", "normal_texture", "occlusion_texture",
  "emissive_texture"];

function suffixOf(name) {
  const dot = name.lastIndexOf(".");
  return dot < 0 ? "" : name.slice(dot).toLowerCase();
}

function dirname(path) {
  const slash = path.lastIndexOf("/");
  return slash < 0 ? "" : path.slice(0, slash);
}

function basename(path) {
  return path.slice(path.lastIndexOf("/") + 1);
}

// posixpath.normpath of a relative path: "./a//b/../c" is "a/c".
function normalize(path) {
  const parts = [];
  for (const part of path.split("/")) {
    if (part === "" || part === ".") continue;
    if (part === ".." && parts.length && parts[parts.length - 1] !== "..") parts.pop();
    else parts.push(part);
  }
  return parts.join("/") || ".";
}

// The canonical form the API accepts; a name that leaves the scene's folder is refused.
function canonical(name, scenePath, what) {
  const relative = name ? normalize(name) : "";
  if (!name || name.startsWith("/") || name.includes("\\") || relative === "." || relative === ".." ||
      relative.startsWith("../")) {
    throw new SceneFileError(`${scenePath}: ${what} "${name}" is not a relative path inside the scene's folder`);
  }
  return relative;
}

function* jsonReferences(scene) {
  const shapes = scene && Array.isArray(scene.shapes) ? scene.shapes : [];
  const meshes = scene && scene.meshes && typeof scene.meshes === "object" ? Object.values(scene.meshes) : [];
  for (const mesh of [...shapes, ...meshes]) {
    if (mesh && typeof mesh.file === "string") yield [mesh.file, "mesh file"];
  }
  const materials = scene && scene.materials && typeof scene.materials === "object" ? scene.materials : {};
  for (const material of Object.values(materials)) {
    if (!material || typeof material !== "object") continue;
    const pbr = material.pbr && typeof material.pbr === "object" ? material.pbr : {};
    for (const texture of [material.diffuse_texture, ...PBR_TEXTURES.map((key) => pbr[key])]) {
      if (texture && typeof texture.image === "string") yield [texture.image, "texture image"];
    }
  }
}

function* objLibraries(text) {
  for (const line of text.split(/\r?\n/)) {
    const words = line.split("#", 1)[0].trim().split(/\s+/);
    if (words[0] === "mtllib") yield* words.slice(1);
  }
}

// A uri's path: %XX escapes decoded. A '%' that starts no escape, or escapes that are not
// UTF-8, name no file the farm would read.
function decodeUri(uri, path, what) {
  try {
    if (!/%(?![0-9A-Fa-f]{2})/.test(uri)) return decodeURIComponent(uri);
  } catch (e) {
    if (!(e instanceof URIError)) throw e;
  }
  throw new SceneFileError(`${path}: ${what} uri "${uri}" has a '%' that is not an escape (a file named with '%' is written %25)`);
}

// A GLB's JSON chunk (the first, right after the 12-byte header), as text.
function glbJson(bytes, path) {
  const view = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  const word = (at) => String.fromCharCode(...bytes.subarray(at, at + 4));
  if (bytes.length < 20 || word(0) !== "glTF") throw new NotItsFormat(path, `${path} is not a GLB file`);
  const length = view.getUint32(12, true);
  if (word(16) !== "JSON" || 20 + length > bytes.length) throw new NotItsFormat(path, `${path}: its first chunk is not JSON`);
  return new TextDecoder().decode(bytes.subarray(20, 20 + length));
}

function namedByGltf(text, path) {
  let documentJson;
  try { documentJson = JSON.parse(text); } catch (e) { throw new NotItsFormat(path, `${path} is not glTF JSON: ${e.message}`); }
  const found = [];
  for (const [kind, what] of [["buffers", "buffer"], ["images", "image"]]) {
    const entries = documentJson && Array.isArray(documentJson[kind]) ? documentJson[kind] : [];
    for (const entry of entries) {
      const uri = entry && entry.uri;
      if (typeof uri === "string" && !uri.startsWith("data:")) found.push([decodeUri(uri, path, what), what]);
    }
  }
  return found;
}

// The files a glTF, GLB or OBJ file names, relative to its own folder (canonical, and
// refused when they leave it: the farm resolves them inside that folder).
async function referencesOfFile(file) {
  const suffix = suffixOf(file.name);
  let named = [];
  if (suffix === ".gltf") named = namedByGltf(await file.text(), file.name);
  else if (suffix === ".glb") named = namedByGltf(glbJson(new Uint8Array(await file.arrayBuffer()), file.name), file.name);
  else if (suffix === ".obj") named = Array.from(objLibraries(await file.text()), (name) => [name, "material library"]);
  return named.map(([name, what]) => [canonical(name, file.name, what), what]);
}

// Finds a referenced file among the chosen ones: by its path under a chosen folder, else
// by its name when only one chosen file has it.
function chosenFile(relative, chosen) {
  const byPath = chosen.filter((file) => file.webkitRelativePath &&
    file.webkitRelativePath.split("/").slice(1).join("/") === relative);
  if (byPath.length === 1) return byPath[0];
  const byName = chosen.filter((file) => file.name === basename(relative));
  return byName.length === 1 ? byName[0] : null;
}

// {scene | null, sceneFile | null, assets: Map(relative path -> File)}: what the scene
// references, found among the chosen files; a missing one is a SceneFileError that says which.
async function sceneFiles(sceneFile, chosen) {
  const assets = new Map();
  const add = (name, from, what) => {
    const relative = canonical(name, from, what);
    const file = chosenFile(relative, chosen);
    if (!file) {
      throw new SceneFileError(`${from} references ${what} "${relative}": choose it among "the files it references"`);
    }
    assets.set(relative, file);
    return relative;
  };
  const suffix = suffixOf(sceneFile.name);
  if (!SCENE_FILE_TYPES.includes(suffix)) {
    throw new SceneFileError(`${sceneFile.name}: expected a tcfarm JSON scene, .gltf, .glb or .obj`);
  }
  if (suffix === ".json") {
    let scene;
    try { scene = JSON.parse(await sceneFile.text()); } catch (e) { throw new NotItsFormat(sceneFile.name, `${sceneFile.name} is not JSON: ${e.message}`); }
    for (const [name, what] of jsonReferences(scene)) add(name, sceneFile.name, what);
    const imported = scene && scene.import && typeof scene.import.file === "string" ? scene.import.file : null;
    if (imported) {
      const relative = add(imported, sceneFile.name, "imported file");
      const file = assets.get(relative);
      const base = dirname(relative);
      for (const [name, what] of await referencesOfFile(file)) add(base ? `${base}/${name}` : name, file.name, what);
    }
    return { scene, sceneFile: null, assets };
  }
  // Any other file goes to the farm as it is, which imports it by its type.
  assets.set(sceneFile.name, sceneFile);
  for (const [name, what] of await referencesOfFile(sceneFile)) add(name, sceneFile.name, what);
  return { scene: null, sceneFile: sceneFile.name, assets };
}

// --- SHA-256 ---------------------------------------------------------------------------

function hex(bytes) {
  return Array.from(new Uint8Array(bytes), (b) => b.toString(16).padStart(2, "0")).join("");
}

// FIPS 180-4 SHA-256 over a File, a piece at a time: for pages the browser does not count
// as a secure context (a farm reached over plain http beyond loopback), which have no
// crypto.subtle.
const SHA256_K = new Uint32Array([
  0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5,
  0xd807aa98, 0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174,
  0xe49b69c1, 0xefbe4786, 0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da,
  0x983e5152, 0xa831c66d, 0xb00327c8, 0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967,
  0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13, 0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85,
  0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819, 0xd6990624, 0xf40e3585, 0x106aa070,
  0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a, 0x5b9cca4f, 0x682e6ff3,
  0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7, 0xc67178f2,
]);

class Sha256 {
  constructor() {
    this.h = new Uint32Array([0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a,
                              0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19]);
    this.w = new Uint32Array(64);
    this.block = new Uint8Array(64);
    this.filled = 0;
    this.length = 0;  // bytes
  }

  update(bytes) {
    this.length += bytes.length;
    let i = 0;
    if (this.filled) {
      const take = Math.min(64 - this.filled, bytes.length);
      this.block.set(bytes.subarray(0, take), this.filled);
      this.filled += take;
      i = take;
      if (this.filled < 64) return;
      this.compress(this.block, 0);
      this.filled = 0;
    }
    for (; i + 64 <= bytes.length; i += 64) this.compress(bytes, i);
    this.block.set(bytes.subarray(i), 0);
    this.filled = bytes.length - i;
  }

  compress(bytes, at) {
    const w = this.w;
    for (let t = 0; t < 16; ++t) {
      const j = at + 4 * t;
      w[t] = (bytes[j] << 24) | (bytes[j + 1] << 16) | (bytes[j + 2] << 8) | bytes[j + 3];
    }
    for (let t = 16; t < 64; ++t) {
      const a = w[t - 15], b = w[t - 2];
      const s0 = ((a >>> 7) | (a << 25)) ^ ((a >>> 18) | (a << 14)) ^ (a >>> 3);
      const s1 = ((b >>> 17) | (b << 15)) ^ ((b >>> 19) | (b << 13)) ^ (b >>> 10);
      w[t] = (w[t - 16] + s0 + w[t - 7] + s1) | 0;
    }
    let [a, b, c, d, e, f, g, h] = this.h;
    for (let t = 0; t < 64; ++t) {
      const s1 = ((e >>> 6) | (e << 26)) ^ ((e >>> 11) | (e << 21)) ^ ((e >>> 25) | (e << 7));
      const t1 = (h + s1 + ((e & f) ^ (~e & g)) + SHA256_K[t] + w[t]) | 0;
      const s0 = ((a >>> 2) | (a << 30)) ^ ((a >>> 13) | (a << 19)) ^ ((a >>> 22) | (a << 10));
      const t2 = (s0 + ((a & b) ^ (a & c) ^ (b & c))) | 0;
      h = g; g = f; f = e; e = (d + t1) | 0; d = c; c = b; b = a; a = (t1 + t2) | 0;
    }
    const s = this.h;
    s[0] += a; s[1] += b; s[2] += c; s[3] += d; s[4] += e; s[5] += f; s[6] += g; s[7] += h;
  }

  digest() {
    const bits = this.length * 8;
    const tail = new Uint8Array(((this.filled + 9 + 63) >> 6) * 64 - this.filled);
    tail[0] = 0x80;
    const view = new DataView(tail.buffer);
    view.setUint32(tail.length - 8, Math.floor(bits / 2 ** 32));
    view.setUint32(tail.length - 4, bits >>> 0);
    this.update(tail);
    const out = new DataView(new ArrayBuffer(32));
    this.h.forEach((word, i) => out.setUint32(4 * i, word));
    return out.buffer;
  }
}

const HASH_PIECE_BYTES = 4 << 20;

async function sha256OfFileInPieces(file) {
  const hash = new Sha256();
  for (let at = 0; at < file.size; at += HASH_PIECE_BYTES) {
    hash.update(new Uint8Array(await file.slice(at, at + HASH_PIECE_BYTES).arrayBuffer()));
  }
  return hex(hash.digest());
}

async function sha256OfFile(file) {
  if (window.crypto && crypto.subtle) return hex(await crypto.subtle.digest("SHA-256", await file.arrayBuffer()));
  return sha256OfFileInPieces(file);
}

// --- the form --------------------------------------------------------------------------

function formNumber(id) {
  const text = $(id).value.trim();
  return text === "" ? undefined : Number(text);
}

// The submission's options from the form, as POST /api/v1/jobs names them.
function submissionOptions(files) {
  const options = {};
  const name = $("submit-name").value.trim();
  options.name = name || $("submit-scene").files[0].name;
  const strategy = $("submit-strategy").value;
  if (strategy) options.strategy = strategy;
  const binWidth = formNumber("submit-bin-width");
  if (binWidth !== undefined) options.bin_width = binWidth;
  const start = formNumber("submit-frame-start");
  const end = formNumber("submit-frame-end");
  if (start !== undefined || end !== undefined) {
    if (start === undefined || end === undefined) throw new SceneFileError("frames: give both the first and the last frame");
    options.frames = { start, end };
  }
  const priority = formNumber("submit-priority");
  if (priority !== undefined && priority !== 0) options.priority = priority;
  const tolerance = formNumber("submit-tolerance");
  if (tolerance !== undefined) options.tolerance = tolerance;
  const view = $("submit-view").value;
  if (view) options.view = view;
  const exposure = formNumber("submit-exposure");
  if (exposure !== undefined && exposure !== 0) options.exposure = exposure;
  const verify = $("submit-verify").value;
  if (verify === "all") options.verify = { frames: "all" };
  else if (verify === "sample") options.verify = { sample: formNumber("submit-verify-sample") || 1 };
  if (files.sceneFile) {
    const imported = {};
    const fps = formNumber("submit-fps");
    if (fps !== undefined) imported.fps = fps;
    const size = $("submit-size").value.trim();
    if (size) {
      const match = /^(\d+)\s*[x×]\s*(\d+)$/i.exec(size);
      if (!match) throw new SceneFileError(`size: "${size}" is not WIDTHxHEIGHT`);
      imported.size = [Number(match[1]), Number(match[2])];
    }
    const spp = formNumber("submit-spp");
    if (spp !== undefined) imported.spp = spp;
    for (const key of ["animation", "camera"]) {
      const value = $(`submit-${key}`).value.trim();
      if (value) imported[key] = value;
    }
    if (Object.keys(imported).length) options.import = imported;
  }
  return options;
}

function submitStatus(text, kind = "note") {
  const node = $("submit-status");
  node.textContent = text;
  node.dataset.kind = kind;
}

function sizeText(bytes) {
  if (bytes >= 2 ** 30) return (bytes / 2 ** 30).toFixed(1) + " GiB";
  if (bytes >= 2 ** 20) return (bytes / 2 ** 20).toFixed(1) + " MiB";
  if (bytes >= 2 ** 10) return (bytes / 2 ** 10).toFixed(1) + " KiB";
  return `${bytes} bytes`;
}

// Lists what the chosen scene references and whether each is among the chosen files.
async function describeChosenScene() {
  const sceneFile = $("submit-scene").files[0];
  const isFile = sceneFile && suffixOf(sceneFile.name) !== ".json";
  $("submit-import").hidden = !isFile;
  if (!sceneFile) {
    submitStatus("");
    return;
  }
  try {
    const files = await sceneFiles(sceneFile, Array.from($("submit-files").files));
    const others = Array.from(files.assets.keys()).filter((name) => name !== files.sceneFile);
    submitStatus(others.length ? `references ${others.length} files, all chosen: ${others.join(", ")}`
                               : "references no other file");
  } catch (error) {
    submitStatus(error.message, error instanceof SceneFileError ? "error" : "note");
  }
}

async function hashAssets(assets) {
  const hashes = new Map();  // relative path -> sha256
  let index = 0;
  for (const [relative, file] of assets) {
    submitStatus(`hashing ${relative} (${++index} of ${assets.size})…`);
    hashes.set(relative, await sha256OfFile(file));
  }
  return hashes;
}

async function uploadAssets(assets, hashes) {
  const { missing } = await sendJson("POST", `${API}/assets/missing`, { hashes: Array.from(new Set(hashes.values())) });
  const byHash = new Map(Array.from(assets, ([relative, file]) => [hashes.get(relative), file]));
  let index = 0;
  for (const sha256 of missing) {
    const file = byHash.get(sha256);
    submitStatus(`uploading ${file.name}, ${sizeText(file.size)} (${++index} of ${missing.length})…`);
    await apiFetch(`${API}/assets/${sha256}`, {
      method: "PUT", body: file, headers: { "Content-Type": "application/octet-stream" },
    });
  }
  return { hashes: Object.fromEntries(hashes), uploaded: missing.length };
}

// A scene file larger than this is checked once uploaded, not sent inline first: the farm's
// JSON bodies are bounded (64 MiB by default) and base64 adds a third.
const INLINE_CHECK_BYTES = 32 * 2 ** 20;

async function base64Of(file) {
  const bytes = new Uint8Array(await file.arrayBuffer());
  let text = "";
  for (let i = 0; i < bytes.length; i += 0x8000) text += String.fromCharCode(...bytes.subarray(i, i + 0x8000));
  return btoa(text);
}

// Asks the farm whether it would take the submission before anything is uploaded
// (POST /api/v1/scenes/check): a file it refuses (an HTML page named .glb) is refused with
// its message and none of its bytes stored. hashes: the other files' (path -> sha256). A
// farm from before the check is not asked.
async function checkScene(sceneFile, files, body, hashes) {
  const check = { ...body };
  const others = new Map(hashes);
  if (files && files.scene) {
    check.scene = files.scene;
  } else {
    check.scene_file = sceneFile.name;
    if (sceneFile.size <= INLINE_CHECK_BYTES) {
      check.scene_file_data = await base64Of(sceneFile);
      others.delete(sceneFile.name);
    }
  }
  if (others.size) check.assets = Object.fromEntries(others);
  submitStatus("checking the scene…");
  try {
    await sendJson("POST", `${API}/scenes/check`, check);
  } catch (error) {
    if (error instanceof ApiError && (error.status === 404 || error.status === 405)) return;
    throw error;
  }
}

async function submitJob(event) {
  event.preventDefault();
  const button = $("submit-button");
  button.disabled = true;
  try {
    const sceneFile = $("submit-scene").files[0];
    if (!sceneFile) throw new SceneFileError("choose a scene file first");
    // A file whose references cannot be read here (an HTML page named .glb) is still shown
    // to the farm, which says what it is.
    let files = null, unreadable = null;
    try {
      files = await sceneFiles(sceneFile, Array.from($("submit-files").files));
    } catch (error) {
      if (!(error instanceof NotItsFormat) || error.path !== sceneFile.name) throw error;
      unreadable = error;
    }
    const body = submissionOptions(files || { scene: null, sceneFile: sceneFile.name });
    const hashes = files ? await hashAssets(files.assets) : new Map();
    // Only where files are about to travel: else the submit itself refuses the same way.
    if (!files || files.assets.size) await checkScene(sceneFile, files, body, hashes);
    if (unreadable) throw unreadable;
    let uploaded = 0;
    if (files.assets.size) {
      const upload = await uploadAssets(files.assets, hashes);
      body.assets = upload.hashes;
      uploaded = upload.uploaded;
    }
    if (files.scene) body.scene = files.scene;
    if (files.sceneFile) body.scene_file = files.sceneFile;
    submitStatus("submitting…");
    const job = await sendJson("POST", `${API}/jobs`, body);
    const sent = files.assets.size ? ` (${files.assets.size} files, ${uploaded} uploaded, the rest already on the farm)` : "";
    submitStatus(`submitted job ${job.id}${sent}`, "ok");
    $("submit-status").dataset.job = String(job.id);
    location.hash = `job=${job.id}`;
    refreshSoon();
  } catch (error) {
    submitStatus(error instanceof ApiError ? `The farm refused the job: ${error.plain}` : error.message, "error");
  } finally {
    button.disabled = false;
  }
}

function initSubmitForm() {
  $("submit-form").addEventListener("submit", submitJob);
  $("submit-scene").addEventListener("change", describeChosenScene);
  $("submit-files").addEventListener("change", describeChosenScene);
  $("submit-verify").addEventListener("change", () => {
    $("submit-verify-sample").hidden = $("submit-verify").value !== "sample";
  });
}
