// The shared corpus (cases.json) against the dashboard's submit.js: for each scene, the files
// sceneFiles() uploads are the files the coordinator reads (scene_files_test.cpp holds the
// coordinator to the same list, tests/scene_files/test_scene_files.py the Python client).
// Run by node's own runner: node --test tests/scene_files/
import assert from "node:assert/strict";
import fs from "node:fs";
import path from "node:path";
import test from "node:test";
import vm from "node:vm";
import { fileURLToPath } from "node:url";

const HERE = path.dirname(fileURLToPath(import.meta.url));
const SUBMIT_JS = path.join(HERE, "..", "..", "services", "dashboard", "submit.js");

// submit.js as the page loads it: a classic script whose top-level names are globals.
function loadSubmitJs() {
  const context = vm.createContext({ TextDecoder, URIError });
  vm.runInContext(fs.readFileSync(SUBMIT_JS, "utf8"), context, { filename: SUBMIT_JS });
  return vm.runInContext("({ sceneFiles, SceneFileError })", context);
}

// A File as a browser's file input gives it; a folder choice sets webkitRelativePath.
function chosen(folder, relative) {
  const bytes = fs.readFileSync(path.join(folder, relative));
  return {
    name: path.basename(relative),
    webkitRelativePath: `case/${relative}`,
    text: async () => bytes.toString("utf8"),
    arrayBuffer: async () => bytes.buffer.slice(bytes.byteOffset, bytes.byteOffset + bytes.length),
  };
}

function filesUnder(folder, prefix = "") {
  return fs.readdirSync(path.join(folder, prefix), { withFileTypes: true }).flatMap((entry) => {
    const relative = prefix ? `${prefix}/${entry.name}` : entry.name;
    return entry.isDirectory() ? filesUnder(folder, relative) : [relative];
  });
}

const { sceneFiles, SceneFileError } = loadSubmitJs();
const cases = JSON.parse(fs.readFileSync(path.join(HERE, "cases.json"), "utf8"));

for (const entry of cases) {
  test(entry.name, async () => {
    // The scene's folder is what a person chooses: every file in it, the scene among them.
    const folder = path.join(HERE, entry.name, path.dirname(entry.scene));
    const files = filesUnder(folder).map((relative) => chosen(folder, relative));
    const scene = files.find((file) => file.webkitRelativePath === `case/${path.basename(entry.scene)}`);
    const others = files.filter((file) => file !== scene);
    if (entry.rejected) {
      await assert.rejects(sceneFiles(scene, others), SceneFileError);
      return;
    }
    const found = await sceneFiles(scene, others);
    const listed = new Set(found.assets.keys());
    listed.add(path.basename(entry.scene));  // a JSON scene travels as the submission itself
    assert.deepEqual([...listed].sort(), [...entry.files].sort());
  });
}
