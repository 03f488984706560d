// Prints the Khronos validator's report (JSON) for each glTF or GLB file named on the
// command line; external buffers resolve beside the file.
const fs = require("fs");
const path = require("path");
const validator = require("gltf-validator");

async function main() {
  const reports = [];
  for (const file of process.argv.slice(2)) {
    const report = await validator.validateBytes(new Uint8Array(fs.readFileSync(file)), {
      uri: path.basename(file),
      externalResourceFunction: (uri) =>
        new Promise((resolve, reject) =>
          fs.readFile(path.join(path.dirname(file), decodeURIComponent(uri)), (error, data) =>
            error ? reject(error.toString()) : resolve(new Uint8Array(data)))),
    });
    reports.push(report);
  }
  process.stdout.write(JSON.stringify(reports));
}

main().catch((error) => {
  process.stderr.write(String(error) + "\n");
  process.exit(1);
});
