// Browser end-to-end tests of `phenomena studio`: Playwright (playwright-core)
// driving Debian's chromium headless. Usage:
//   node e2e.mjs PATH/TO/phenomena OUT_DIR
// Starts the studio on a free port, runs every check, writes OUT_DIR/studio-snow.glb
// (validated by .ci/run with the Khronos validator) and OUT_DIR/studio-e2e.json (the
// measured preview rates and change-to-frame latencies), and exits non-zero on failure.
import { chromium } from 'playwright-core';
import { spawn, spawnSync } from 'node:child_process';
import { mkdirSync, writeFileSync, readdirSync, mkdtempSync, symlinkSync } from 'node:fs';
import { join } from 'node:path';
import { tmpdir } from 'node:os';
import assert from 'node:assert/strict';

const [bin, outDir] = process.argv.slice(2);
if (!bin || !outDir) {
  console.error('usage: node e2e.mjs PATH/TO/phenomena OUT_DIR');
  process.exit(2);
}
mkdirSync(outDir, { recursive: true });
const work = mkdtempSync(join(tmpdir(), 'studio-e2e-'));

// Session folders go to a temporary folder of this test's own, so the hostile-upload
// check can find a session's folder and put a FIFO and a symlink in it.
const sessionsTmp = join(work, 'tmp');
mkdirSync(sessionsTmp);
const server = spawn(bin, ['studio', '--port', '0', '--out', join(work, 'renders')], {
  stdio: ['ignore', 'pipe', 'inherit'],
  env: { ...process.env, TMPDIR: sessionsTmp },
});
const url = await new Promise((resolve, reject) => {
  const timer = setTimeout(() => reject(new Error('the studio did not start within 60 s')), 60000);
  server.stdout.on('data', (d) => {
    const m = /serving (\S+)/.exec(String(d));
    if (m) {
      clearTimeout(timer);
      resolve(m[1]);
    }
  });
  server.on('exit', (code) => reject(new Error(`the studio exited with ${code}`)));
});

const browser = await chromium.launch({
  executablePath: process.env.CHROMIUM || '/usr/bin/chromium',
  args: ['--no-sandbox', '--disable-gpu', '--disable-quic', '--no-first-run', '--disable-background-networking',
    '--disable-component-update', '--disable-sync'],
});
// The size of a laptop's browser window: every tab's preview must fit it.
const page = await browser.newPage({ viewport: { width: 1280, height: 720 }, acceptDownloads: true });
const consoleErrors = [];
page.on('console', (m) => { if (m.type() === 'error') consoleErrors.push(m.text()); });
page.on('pageerror', (e) => consoleErrors.push(e.message));

const report = { url, tabs: {} };
const results = [];
async function check(name, fn) {
  const t0 = Date.now();
  try {
    await fn();
    results.push({ name, ok: true });
    console.log(`ok    ${name} (${Date.now() - t0} ms)`);
  } catch (e) {
    results.push({ name, ok: false, error: String(e.stack || e) });
    console.log(`FAIL  ${name}: ${e.stack || e}`);
    await page.screenshot({ path: join(outDir, `fail-${name.replace(/\W+/g, '-')}.png`) }).catch(() => {});
  }
}

const studio = (expr) => page.evaluate(expr);
async function until(what, fn, timeoutMs = 30000) {
  const end = Date.now() + timeoutMs;
  for (;;) {
    const v = await fn();
    if (v) return v;
    if (Date.now() > end) throw new Error(`timed out after ${timeoutMs} ms waiting for ${what}`);
    await page.waitForTimeout(100);
  }
}

// Luminance statistics of the preview, and the centroid of its bright pixels.
function previewStats() {
  return page.evaluate(() => {
    const c = document.getElementById('preview');
    const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
    let n = 0, sum = 0, sum2 = 0, bx = 0, bw = 0, hash = 0;
    for (let i = 0; i < d.length; i += 4) {
      const y = 0.2126 * d[i] + 0.7152 * d[i + 1] + 0.0722 * d[i + 2];
      sum += y; sum2 += y * y; n += 1;
      if (d[i] > 200 && d[i + 1] > 100) { bx += ((i / 4) % c.width); bw += 1; }
      hash = (hash * 31 + d[i] + 7 * d[i + 1]) >>> 0;
    }
    const mean = sum / n;
    return { mean, sd: Math.sqrt(Math.max(sum2 / n - mean * mean, 0)), brightX: bw ? bx / bw : null, bright: bw, hash, width: c.width };
  });
}

async function openTab(phenomenon) {
  await page.click(`#tabs button[data-phenomenon="${phenomenon}"]`);
  // A shot's scene holds several phenomena's tables (the flame's and the dust's, say).
  const tables = phenomenon === 'shot' ? ['flame', 'sparkle'] : [phenomenon];
  const held = tables.map((t) => `window.studio.scene['${t}'] !== undefined`).join(' && ');
  await until(`a ${phenomenon} scene`, () => studio(`window.studio.phenomenon === '${phenomenon}' && window.studio.scene && ${held}`));
}

// Frames shown per second over `ms` of play, and the change-to-first-frame latency of
// three seed changes (median).
async function measure(phenomenon) {
  await page.click('#play');
  const f0 = await studio('window.studio.frames');
  const t0 = Date.now();
  // The server's own timings of the frames shown meanwhile (step, render, tone map), sampled.
  const parts = { step_ms: [], render_ms: [], tonemap_ms: [] };
  while (Date.now() - t0 < 5000) {
    await page.waitForTimeout(250);
    const c = await studio('window.studio.counters');
    if (c) for (const k of Object.keys(parts)) parts[k].push(c[k]);
  }
  const fps = ((await studio('window.studio.frames')) - f0) / ((Date.now() - t0) / 1000);
  const median = (xs) => xs.slice().sort((a, b) => a - b)[Math.floor(xs.length / 2)];
  const latencies = [];
  for (const seed of [11, 12, 13]) {
    const n = await studio('window.studio.latencies.length');
    await page.fill('#seed', String(seed));
    await page.dispatchEvent('#seed', 'change');
    await until('the first frame after a change', () => studio(`window.studio.latencies.length > ${n}`), 30000);
    latencies.push(await studio('window.studio.latencies[window.studio.latencies.length - 1]'));
  }
  latencies.sort((a, b) => a - b);
  report.tabs[phenomenon] = {
    fps: Number(fps.toFixed(2)),
    latency_ms: latencies.map((x) => Math.round(x)),
    median_latency_ms: Math.round(latencies[1]),
    server_median_ms: Object.fromEntries(Object.entries(parts).map(([k, xs]) => [k, xs.length ? Number(median(xs).toFixed(1)) : null])),
  };
}

await page.goto(url);
await until('the session', () => studio('window.studio && window.studio.session'));

await check('the page loads with no console errors', async () => {
  await until('a first frame', () => studio('window.studio.frames > 0'));
  assert.deepEqual(consoleErrors, []);
});

for (const phenomenon of ['aurora', 'flame', 'snow', 'sparkle', 'shot']) {
  await check(`${phenomenon}: the preview shows a non-uniform image within a few seconds`, async () => {
    await openTab(phenomenon);
    const t0 = Date.now();
    const s = await until('a non-uniform preview', async () => {
      const st = await previewStats();
      return st.sd > 3 ? st : null;
    }, 20000);
    report.tabs[phenomenon] = { first_image_ms: Date.now() - t0 };
    assert.ok(s.sd > 3, JSON.stringify(s));
    // The preview fits the 1280x720 window, above the fold, beside the panel.
    const box = await page.locator('#preview').boundingBox();
    const panel = await page.locator('#panel').boundingBox();
    assert.ok(box.x >= 0 && box.y >= 0 && box.x + box.width <= 1280 && box.y + box.height <= 720, `preview at ${JSON.stringify(box)}`);
    assert.ok(panel.x >= box.x + box.width, `the panel ${JSON.stringify(panel)} overlaps the preview ${JSON.stringify(box)}`);
    assert.ok(await page.locator('#scrubber').boundingBox().then((b) => b.y + b.height <= 720), 'the scrubber is above the fold');
    await measure(phenomenon);
    report.tabs[phenomenon].first_image_ms = Date.now() - t0;
  });
}

await check('shot: each phenomenon has its own sections of controls', async () => {
  await openTab('shot');
  const titles = await page.evaluate(() => [...document.querySelectorAll('details > summary')].map((e) => e.textContent));
  for (const t of ['[render.aurora]', '[render.snow]', '[render.sparkle]', '[render.flame]', '[flame.emitter]', '[sparkle.population]', '[snow]']) {
    assert.ok(titles.includes(t), `${t} in ${JSON.stringify(titles)}`);
  }
});

// --- aurora editor ---
async function kmToPage(canvasId, p) {
  return page.evaluate(([id, p]) => {
    const c = document.getElementById(id);
    c.scrollIntoView({ block: 'nearest' }); // the editor sits below the preview
    const r = c.getBoundingClientRect();
    const [x, y] = window.studio.editor.toPx(c, p);
    return [r.left + (x * r.width) / c.width, r.top + (y * r.height) / c.height];
  }, [canvasId, p]);
}
async function dragKm(canvasId, from, to, steps = 12) {
  const a = await kmToPage(canvasId, from);
  const b = await kmToPage(canvasId, to);
  await page.mouse.move(a[0], a[1]);
  await page.mouse.down();
  await page.mouse.move(b[0], b[1], { steps });
  await page.mouse.up();
}
async function clickKm(canvasId, p) {
  const a = await kmToPage(canvasId, p);
  await page.mouse.click(a[0], a[1]);
}
const shapeOf = (k) => studio(`JSON.stringify(window.studio.editor.state.keyframes[${k}].shape)`).then(JSON.parse);
// A merge and a split each add two control points (the joined ends meet at the new
// pair; a split's new ends part from it) and rewire the links.
const links = (shape) => JSON.stringify(shape.next);
const generation = () => studio('window.studio.generation');

await check('aurora: a drag on the source canvas creates control points and the preview changes', async () => {
  await openTab('aurora');
  await page.click('#clear-shapes');
  await until('an empty source', async () => (await shapeOf(0)).points.length === 0);
  const before = await previewStats();
  const g = await generation();
  await dragKm('source-canvas', [60, 150], [190, 150]);
  await until('control points on the source', async () => (await shapeOf(0)).points.length > 0);
  const n = await studio('window.studio.editor.state.control_points');
  assert.equal((await shapeOf(0)).points.length, n);
  await until('a frame of the new shape', () => studio(`window.studio.generation > ${g} && window.studio.frames > 0`));
  const after = await until('a changed preview', async () => {
    const s = await previewStats();
    return s.hash !== before.hash && s.sd > 1 ? s : null;
  }, 20000);
  assert.notEqual(after.hash, before.hash);
});

await check('aurora: a crossing stroke is refused with a visible message', async () => {
  const refusals = await studio('window.studio.messages.filter((m) => m.kind === "refused").length');
  const pts = (await shapeOf(0)).points.length;
  await dragKm('source-canvas', [120, 60], [120, 260]);
  await until('a refusal', () => studio(`window.studio.messages.filter((m) => m.kind === "refused").length > ${refusals}`));
  const text = await page.textContent('#messages');
  assert.match(text, /crosses sheet 0/);
  assert.equal((await shapeOf(0)).points.length, pts, 'the crossing stroke was not added');
});

await check('aurora: split and merge clicks change the shape', async () => {
  // A second source sheet, then both target sheets (the highlighted placeholders).
  await dragKm('source-canvas', [210, 150], [340, 150]);
  await until('two source sheets', async () => new Set((await shapeOf(0)).sheet).size === 2);
  await dragKm('target-canvas', [60, 250], [190, 250]);
  await until('target sheet 0 drawn', () => studio('window.studio.editor.state.keyframes[1].drawn[0] === true'));
  await dragKm('target-canvas', [210, 250], [340, 250]);
  await until('target sheet 1 drawn', () => studio('window.studio.editor.state.keyframes[1].drawn[1] === true'));
  // Merge: the right end of sheet 0 and the left end of sheet 1.
  const before = await shapeOf(1);
  await page.selectOption('#target-tool', 'merge');
  await clickKm('target-canvas', [190, 250]);
  await clickKm('target-canvas', [210, 250]);
  await until('a merge', async () => (await shapeOf(1)).points.length === before.points.length + 2);
  const merged = await shapeOf(1);
  assert.notEqual(links(merged), links(before));
  // Split: the middle of sheet 0.
  await page.selectOption('#target-tool', 'split');
  await clickKm('target-canvas', [125, 250]);
  await until('a split', async () => (await shapeOf(1)).points.length === merged.points.length + 2);
  assert.notEqual(links(await shapeOf(1)), links(merged));
  await page.selectOption('#target-tool', 'draw');
});

await check('aurora: keyframes can be added, moved and deleted', async () => {
  const count = () => studio('window.studio.editor.state.keyframes.length');
  const k0 = await count();
  await page.click('#add-keyframe');
  await until('a new keyframe', async () => (await count()) === k0 + 1);
  await page.fill('#keyframe-frame', '400');
  await page.dispatchEvent('#keyframe-frame', 'change');
  await until('the keyframe moved', () => studio(`window.studio.editor.state.keyframes[${k0}].frame === 400`));
  await page.click('#delete-keyframe');
  await until('the keyframe deleted', async () => (await count()) === k0);
});

// --- flame wind ---
// A preset by its menu entry (the shipped scene's name).
async function preset(name) {
  const g = await generation();
  await page.selectOption('#builtin', name);
  await until(`the preset ${name}`, () => studio(`window.studio.generation > ${g} && window.studio.name === '${name}' && window.studio.lastFrame >= 0`));
}

await check('flame: a drag on the preview moves the flame toward the drag, and the wind control shows it', async () => {
  await openTab('flame');
  await preset('flame-paper');
  await page.click('#play');
  await page.waitForTimeout(3000);
  const calm = await previewStats();
  assert.ok(calm.bright > 50, `no flame to see: ${JSON.stringify(calm)}`);
  const box = await page.locator('#preview').boundingBox();
  const cx = box.x + box.width / 2, cy = box.y + box.height / 2;
  await page.mouse.move(cx, cy);
  await page.mouse.down();
  await page.mouse.move(cx + box.width * 0.35, cy, { steps: 8 });
  await page.mouse.up();
  const windy = await until('the flame to lean right', async () => {
    const s = await previewStats();
    return s.brightX > calm.brightX + 15 ? s : null;
  }, 15000);
  report.flame_wind = { calm_x: calm.brightX, windy_x: windy.brightX };
  const wind = await page.$$eval('[id="ctl-flame-wind-force_n_m3"], .control[data-path="flame.wind.force_n_m3"] input', (is) => is.map((i) => Number(i.value)));
  assert.ok(wind.length >= 3 && wind[0] > 0, `the wind control shows the wind blown: ${wind}`);
  assert.ok(await page.locator('#scene-name.dirty').count() === 1, 'the scene is marked as changed');
});

// --- snow GLB download ---
await check('snow: the GLB download is a glTF binary', async () => {
  await openTab('snow');
  await page.click('#play');
  // Switching tabs restarts the scene: wait for snow to lie (10 steps of this generation).
  await until('snow to accumulate', () => studio('window.studio.lastFrame >= 10'));
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#snow-glb')]);
  const path = join(outDir, 'studio-snow.glb');
  await download.saveAs(path);
  const bytes = (await import('node:fs')).readFileSync(path);
  assert.equal(bytes.subarray(0, 4).toString('latin1'), 'glTF');
});

// --- hostile uploads: a page cannot make the studio read other files ---
// One triangle, and a glTF whose only buffer has the URI given.
const triangle = Buffer.from(new Float32Array([0, 0, 0, 0, 0, 4, 4, 0, 0]).buffer);
const gltf = (uri) => Buffer.from(JSON.stringify({
  asset: { version: '2.0' }, scene: 0, scenes: [{ nodes: [0] }], nodes: [{ mesh: 0 }],
  meshes: [{ primitives: [{ attributes: { POSITION: 0 } }] }],
  accessors: [{ bufferView: 0, componentType: 5126, count: 3, type: 'VEC3', max: [4, 0, 4], min: [0, 0, 0] }],
  bufferViews: [{ buffer: 0, byteLength: 36 }], buffers: [{ uri, byteLength: 36 }],
}));

await check('snow: hostile glTF buffer URIs are refused without reading; this tab and others keep working', async () => {
  await openTab('snow');
  const folders = readdirSync(sessionsTmp).filter((f) => f.startsWith('phenomena-studio-'));
  assert.equal(folders.length, 1, `one session folder: ${folders}`);
  const folder = join(sessionsTmp, folders[0]);
  // What a page cannot upload but another program might have left there.
  assert.equal(spawnSync('mkfifo', [join(folder, 'pipe.bin')]).status, 0);
  symlinkSync('/etc/hostname', join(folder, 'link.bin'));
  const cases = [
    ['/etc/hostname', 'absolute paths are refused'],
    ['/dev/zero', 'absolute paths are refused'],
    ['../../../../etc/hostname', 'plain name'],
    ['pipe.bin', 'not a regular file'],
    ['link.bin', 'symlink'],
  ];
  for (const [uri, why] of cases) {
    const n = await studio('window.studio.messages.length');
    await page.setInputFiles('#mesh-upload', { name: 'm.gltf', mimeType: 'model/gltf+json', buffer: gltf(uri) });
    const m = await until(`the refusal of ${uri}`, () => studio(
      `window.studio.messages.slice(${n}).find((x) => x.kind === 'error' && x.text.includes('its glTF buffer'))`), 20000);
    assert.ok(m.text.includes(`geometry.mesh = "m.gltf": its glTF buffer ${JSON.stringify(uri)}`), m.text);
    assert.ok(m.text.includes(why), `${uri}: ${m.text}`);
    assert.ok(!m.text.includes(sessionsTmp), `the message reveals the server's folders: ${m.text}`);
  }
  // A glTF with its buffer beside it works in the same tab.
  const g = await generation();
  await page.setInputFiles('#mesh-upload', [
    { name: 'good.gltf', mimeType: 'model/gltf+json', buffer: gltf('tri.bin') },
    { name: 'tri.bin', mimeType: 'application/octet-stream', buffer: triangle },
  ]);
  await until('a frame of the uploaded mesh', () => studio(`window.studio.generation > ${g} && window.studio.lastFrame >= 0`), 30000);
  // Another tab works meanwhile.
  const other = await browser.newPage();
  await other.goto(url);
  await other.waitForFunction(() => window.studio && window.studio.frames > 0, null, { timeout: 30000 });
  await other.close();
});

// --- save, then render the saved file ---
await check('save scene, then phenomena render on the saved file works', async () => {
  await openTab('sparkle');
  await page.fill('#seed', '5');
  await page.dispatchEvent('#seed', 'change');
  await until('seed 5', () => studio('window.studio.scene.scene.seed === 5'));
  const [download] = await Promise.all([page.waitForEvent('download'), page.click('#save')]);
  const saved = join(work, 'saved.toml');
  await download.saveAs(saved);
  const out = join(work, 'render');
  const r = spawnSync(bin, ['render', saved, '--out', out, '--frames', '0..2', '--width', '64', '--height', '36'], { encoding: 'utf8' });
  assert.equal(r.status, 0, r.stderr);
  assert.deepEqual(readdirSync(out).filter((f) => f.endsWith('.png')).sort(), ['frame_00000.png', 'frame_00001.png']);
});

await check('render final writes the frames with progress', async () => {
  await openTab('flame');
  const n = await studio('window.studio.messages.length');
  await page.fill('#final-first', '0');
  await page.fill('#final-last', '2');
  await page.click('#render-final');
  const done = await until('the render to finish', async () => {
    const m = await studio(`window.studio.messages.slice(${n}).find((x) => x.text.startsWith('render final:') || x.kind === 'error')`);
    return m;
  }, 60000);
  assert.equal(done.kind, 'notice', done.text);
  const dir = /written to (.*)$/.exec(done.text)[1];
  assert.deepEqual(readdirSync(dir).sort(), ['frame_00000.png', 'frame_00001.png', 'frame_00002.png', 'scene.toml']);
  assert.equal(await page.getAttribute('#final-progress', 'value'), '3');
});

await check('render final writes volumes and flipbooks', async () => {
  await openTab('flame');
  const formats = await page.$$eval('#final-format option', (os) => os.map((o) => o.value));
  assert.deepEqual(formats, ['png', 'exr', 'vdb', 'ply', 'flipbook']);
  for (const [format, files] of [['vdb', ['frame_00000.vdb', 'frame_00000.vdb.json', 'frame_00001.vdb', 'frame_00001.vdb.json', 'scene.toml']],
                                 ['flipbook', ['flipbook.json', 'flipbook.png', 'scene.toml']]]) {
    const n = await studio('window.studio.messages.length');
    await page.fill('#final-first', '0');
    await page.fill('#final-last', '1');
    await page.selectOption('#final-format', format);
    await page.click('#render-final');
    const done = await until(`the ${format} render to finish`, async () => {
      const m = await studio(`window.studio.messages.slice(${n}).find((x) => x.text.startsWith('render final:') || x.kind === 'error')`);
      return m;
    }, 60000);
    assert.equal(done.kind, 'notice', done.text);
    const dir = /written to (.*)$/.exec(done.text)[1];
    assert.deepEqual(readdirSync(dir).sort(), files);
  }
  await openTab('snow');
  assert.deepEqual(await page.$$eval('#final-format option', (os) => os.map((o) => o.value)), ['png', 'exr']);
});


// --- the timeline ---
const time = () => studio('window.studio.time');
await check('timeline: play loops at the scene\'s end, or stops there with the loop off', async () => {
  await openTab('flame');
  await preset('flame-paper');
  // The [scene] table's controls.
  await page.locator('details', { has: page.locator('summary', { hasText: /^\[scene\]$/ }) }).evaluate((d) => { d.open = true; });
  await page.fill('#ctl-scene-frames', '20');
  await page.dispatchEvent('#ctl-scene-frames', 'change');
  await until('a 20-frame scene', async () => (await time())?.length === 20);
  await page.click('#play');
  await until('frame 19, then frame 0 again', () => studio(`(() => {
    const f = window.studio.shownFrames; const i = f.lastIndexOf(19);
    return i >= 0 && f.slice(i + 1).some((x) => x < 5);
  })()`), 30000);
  const shown = await studio('window.studio.shownFrames');
  assert.ok(Math.max(...shown) <= 19, `no frame past the end: ${shown}`);
  await page.uncheck('#loop');
  await until('play to stop at the last frame', async () => {
    const t = await time();
    return t && !t.playing && t.frame === 19 && t.looping === false;
  }, 30000);
  assert.equal(await page.textContent('#frame-readout'), '19 / 19');
});

await check('timeline: the scrubber shows frame N, and a render-only change keeps it', async () => {
  await page.$eval('#scrubber', (e) => { e.value = '7'; e.dispatchEvent(new Event('input')); e.dispatchEvent(new Event('change')); });
  await until('frame 7 shown', async () => {
    const t = await time();
    return t && t.frame === 7 && t.target == null && (await studio('window.studio.lastFrame')) === 7;
  });
  assert.equal(await page.textContent('#frame-readout'), '7 / 19');
  // The exposure control, found by its label.
  const g = await generation();
  await page.getByLabel('exposure', { exact: true }).fill('1.5');
  await page.getByLabel('exposure', { exact: true }).dispatchEvent('change');
  const c = await until('the render-only change', () => studio(`window.studio.lastChange && window.studio.lastChange.generation > ${g} && window.studio.lastChange`));
  assert.deepEqual([c.change, c.frame], ['render', 7]);
  await until('frame 7 drawn again', () => studio(`window.studio.generation > ${g} && window.studio.lastFrame === 7`));
  assert.match(await page.textContent('#time-status'), /drawn again from the running simulation/);
  assert.ok(await page.locator('#scene-name.dirty').count() === 1, 'the scene is marked as changed');
});

await check('undo restores the old value (Ctrl+Z), redo brings it back, Space plays and pauses', async () => {
  await page.evaluate(() => document.activeElement && document.activeElement.blur());
  await page.keyboard.press('Control+z');
  await until('exposure 0 again', () => studio('window.studio.scene.scene.exposure_ev === 0'));
  assert.equal(await page.getByLabel('exposure', { exact: true }).inputValue(), '0');
  assert.equal((await time()).frame, 7, 'undo keeps the frame');
  await page.keyboard.press('Control+Shift+Z');
  await until('exposure 1.5 again', () => studio('window.studio.scene.scene.exposure_ev === 1.5'));
  await page.keyboard.press('Space');
  await until('playing', async () => (await time()).playing === true);
  await page.keyboard.press('Space');
  await until('paused', async () => (await time()).playing === false);
  const at = (await time()).frame;
  await page.keyboard.press('ArrowLeft');
  await until('one frame back', async () => (await time()).frame === at - 1 && (await time()).target == null);
});

await check('render final writes exactly frames A..B and says where', async () => {
  const n = await studio('window.studio.messages.length');
  await page.selectOption('#final-format', 'png');
  await page.fill('#final-first', '4');
  await page.fill('#final-last', '6');
  await page.click('#render-final');
  await until('the render to finish', () => studio(`window.studio.messages.slice(${n}).some((x) => x.text.startsWith('render final:') || x.kind === 'error')`), 60000);
  const r = await studio('window.studio.lastRender');
  assert.ok(r, 'a rendered message');
  assert.deepEqual(readdirSync(r.dir).sort(), ['frame_00004.png', 'frame_00005.png', 'frame_00006.png', 'scene.toml']);
  assert.match(await page.textContent('#final-status'), new RegExp(`frames 4 to 6 in ${r.dir.replace(/[.*+?^${}()|[\]\\]/g, '\\$&')}`));
});

await check('numbers show as written and messages clear when resolved', async () => {
  await openTab('sparkle');
  assert.equal(await page.inputValue('#ctl-sparkle-phong-threshold_i_e'), '0.0025');
  await page.fill('#seed', '-4');
  await page.dispatchEvent('#seed', 'change');
  await until('an error', () => studio(`document.querySelectorAll('#messages .error').length > 0`));
  await page.fill('#seed', '4');
  await page.dispatchEvent('#seed', 'change');
  await until('the error gone', () => studio(`window.studio.scene.scene.seed === 4 && document.querySelectorAll('#messages .error').length === 0`));
});

await check('no console errors during the whole run', async () => {
  assert.deepEqual(consoleErrors, []);
});

report.results = results;
writeFileSync(join(outDir, 'studio-e2e.json'), JSON.stringify(report, null, 2));
console.log(JSON.stringify(report.tabs));
await browser.close();
server.kill();
const failed = results.filter((r) => !r.ok).length;
console.log(`${results.length - failed} passed, ${failed} failed`);
process.exit(failed ? 1 : 0);
