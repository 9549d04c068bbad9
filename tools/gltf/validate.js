// Usage: node validate.js FILE.glb — prints the validator's issue counts as JSON and exits
// 1 if it reports any error.
const fs = require('fs');
const validator = require('gltf-validator');
const bytes = new Uint8Array(fs.readFileSync(process.argv[2]));
validator.validateBytes(bytes).then((report) => {
  const i = report.issues;
  console.log(JSON.stringify({ errors: i.numErrors, warnings: i.numWarnings, infos: i.numInfos, messages: i.messages.filter((m) => m.severity === 0).slice(0, 10) }));
  process.exit(i.numErrors > 0 ? 1 : 0);
}, (e) => { console.error(e); process.exit(2); });
