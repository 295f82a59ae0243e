// Validate one .gltf/.glb with the Khronos glTF validator (npm gltf-validator) and print the
// report as JSON on stdout. Exit status: 0 when the report has no errors, 1 when it has errors,
// 2 when the file could not be validated at all (unreadable, not glTF).
//
//   node tests/tools/validate_gltf.mjs path/to/scene.gltf [--max-issues N]
//
// External resources (.bin buffers, images) are loaded relative to the file, so a missing or
// short buffer is reported as an error rather than skipped.
import fs from "node:fs";
import path from "node:path";
import validator from "gltf-validator";

const args = process.argv.slice(2);
const file = args.find((a) => !a.startsWith("--"));
if (!file) {
  console.error("usage: node validate_gltf.mjs FILE.gltf|FILE.glb [--max-issues N]");
  process.exit(2);
}
const maxIdx = args.indexOf("--max-issues");
const maxIssues = maxIdx >= 0 ? Number(args[maxIdx + 1]) : 0;
const fullpath = path.resolve(file);

let bytes;
try {
  bytes = new Uint8Array(fs.readFileSync(fullpath));
} catch (err) {
  console.error(`validate_gltf: cannot read ${fullpath}: ${err.message}`);
  process.exit(2);
}

try {
  const report = await validator.validateBytes(bytes, {
    uri: path.basename(fullpath),
    maxIssues,
    writeTimestamp: false,
    externalResourceFunction: (uri) =>
      fs.promises.readFile(path.resolve(path.dirname(fullpath), decodeURIComponent(uri)))
        .then((data) => new Uint8Array(data)),
  });
  console.log(JSON.stringify(report, null, 2));
  process.exit(report.issues.numErrors > 0 ? 1 : 0);
} catch (err) {
  console.error(`validate_gltf: ${fullpath} could not be validated: ${err}`);
  process.exit(2);
}
