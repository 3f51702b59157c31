// Validates one glTF file (.glb, or .gltf with its .bin) with the Khronos glTF validator and
// prints the report as JSON on stdout.
// Usage: node validate.js VALIDATOR_DIR FILE
// Exit status: 0 when the report has no errors, 1 when it has, 2 when the validator could not
// run (missing package, unreadable file).
'use strict';
const fs = require('fs');
const path = require('path');

const [validatorDir, file] = process.argv.slice(2);
if (!validatorDir || !file) {
  console.error('usage: node validate.js VALIDATOR_DIR FILE');
  process.exit(2);
}
let validator;
try {
  validator = require(path.resolve(validatorDir));
} catch (e) {
  console.error('gltf-validator not found in ' + validatorDir + ': ' + e.message);
  process.exit(2);
}
const full = path.resolve(file);
validator.validateBytes(new Uint8Array(fs.readFileSync(full)), {
  uri: path.basename(full),
  maxIssues: 0,  // every issue
  externalResourceFunction: (uri) => new Promise((resolve, reject) => {
    fs.readFile(path.resolve(path.dirname(full), decodeURIComponent(uri)),
                (err, data) => err ? reject(err.toString()) : resolve(data));
  }),
}).then((report) => {
  console.log(JSON.stringify(report));
  process.exit(report.issues.numErrors === 0 ? 0 : 1);
}, (err) => {
  console.error('validator could not read ' + file + ': ' + err);
  process.exit(2);
});
