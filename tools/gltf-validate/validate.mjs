// Validate glTF/GLB files with the Khronos glTF-Validator; exit 1 on any error or
// warning (exported GLB must pass with 0 errors and 0 warnings).
//   node tools/gltf-validate/validate.mjs FILE.glb [...]
import { readFileSync } from "node:fs";
import { createRequire } from "node:module";
const validator = createRequire(import.meta.url)("gltf-validator");

let failed = false;
for (const file of process.argv.slice(2)) {
  const report = await validator.validateBytes(new Uint8Array(readFileSync(file)), { uri: file });
  const { numErrors, numWarnings, numInfos } = report.issues;
  console.log(`${file}: ${numErrors} errors, ${numWarnings} warnings, ${numInfos} infos`);
  for (const m of report.issues.messages) {
    if (m.severity <= 1) console.log(`  ${m.code}: ${m.message} (${m.pointer ?? ""})`);
  }
  if (numErrors > 0 || numWarnings > 0) failed = true;
}
process.exit(failed ? 1 : 0);
