// Convert the public-domain meshes of the npm packages `bunny` (1.0.1, the Stanford
// bunny, 3D Scanning Repository) and `teapot` (1.0.0, Martin Newell's Utah teapot) to
// OBJ test data for the snow crate. Run once:
//   cd tools/mesh-convert && npm install --no-save bunny@1.0.1 teapot@1.0.0 && node convert.mjs
// It writes ../../tests/data/bunny.obj and ../../tests/data/teapot.obj.
import { createRequire } from "node:module";
import { writeFileSync } from "node:fs";

const require = createRequire(import.meta.url);
for (const [name, pkg, credit] of [
  ["bunny", "bunny", "Stanford bunny, Stanford 3D Scanning Repository, via npm bunny@1.0.1 (Public Domain)"],
  ["teapot", "teapot", "Utah teapot, (c) 1984 Martin Newell, via npm teapot@1.0.0 (Public Domain)"],
]) {
  const mesh = require(pkg);
  const lines = [`# ${credit}`, `# converted by tools/mesh-convert/convert.mjs; y is up`, `o ${name}`];
  for (const [x, y, z] of mesh.positions) lines.push(`v ${x} ${y} ${z}`);
  for (const cell of mesh.cells) lines.push(`f ${cell.map((i) => i + 1).join(" ")}`);
  writeFileSync(new URL(`../../tests/data/${name}.obj`, import.meta.url), lines.join("\n") + "\n");
  console.log(`${name}: ${mesh.positions.length} vertices, ${mesh.cells.length} faces`);
}
