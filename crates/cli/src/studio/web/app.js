// phenomena studio: one WebSocket per tab; the server simulates and renders, this page
// draws, controls and shows. Test hooks live on `window.studio`.
import { buildForm, markIssues, getPath } from './form.js';
import { AuroraEditor } from './aurora.js';

const $ = (id) => document.getElementById(id);
const studio = {
  session: null, phenomenon: null, generation: 0, scene: null, frames: 0, fps: 0,
  latencies: [], messages: [], counters: null, lastImage: null, editor: null,
};
window.studio = studio;

const scenes = {}; // last scene JSON per phenomenon, restored when a tab is revisited
let hello = null;
let catalogue = null;
let ws = null;
let change = null; // { at, generation }: a parameter change waiting for its first frame
const shown = []; // display times of recent frames

const preview = $('preview');
const ctx = preview.getContext('2d');

function send(msg) {
  if (ws && ws.readyState === WebSocket.OPEN) ws.send(JSON.stringify(msg));
}

// A change that will give a new generation: time it to its first frame.
function sendChange(msg) {
  change = { at: performance.now(), generation: studio.generation };
  send(msg);
}

function setParam(path, value) {
  sendChange({ type: 'set', path, value });
}

function say(kind, text) {
  studio.messages.push({ kind, text });
  const box = $('messages');
  const d = document.createElement('div');
  d.className = kind;
  d.textContent = text;
  box.prepend(d);
  while (box.children.length > 4) box.lastChild.remove();
}

const editor = new AuroraEditor({
  source: $('source-canvas'), target: $('target-canvas'), strip: $('keyframes'), tool: $('target-tool'),
  hint: $('editor-hint'), caption: $('target-caption'), clear: $('clear-shapes'),
  send: (m) => sendChange(m),
});
studio.editor = editor;

function selectTab(phenomenon) {
  studio.phenomenon = phenomenon;
  for (const b of document.querySelectorAll('#tabs button')) {
    b.setAttribute('aria-selected', String(b.dataset.phenomenon === phenomenon));
  }
  $('aurora-editor').hidden = phenomenon !== 'aurora';
  $('wind-hint').hidden = phenomenon !== 'flame';
  const select = $('builtin');
  select.replaceChildren();
  for (const b of hello.builtins.filter((x) => x.phenomenon === phenomenon)) {
    const o = document.createElement('option');
    o.value = b.name;
    o.textContent = b.name;
    select.append(o);
  }
  const formats = $('final-format');
  formats.replaceChildren();
  for (const f of hello.phenomena.find((p) => p.name === phenomenon).formats) {
    const o = document.createElement('option');
    o.value = f;
    o.textContent = f;
    formats.append(o);
  }
  buildExtras(phenomenon);
  $('counters').textContent = '';
  if (scenes[phenomenon]) sendChange({ type: 'scene', phenomenon, scene: scenes[phenomenon] });
  else sendChange({ type: 'builtin', name: select.options[0].value });
  history.replaceState(null, '', `#${phenomenon}`);
}

function buildExtras(phenomenon) {
  const box = $('extras');
  box.replaceChildren();
  // Uploads go to this session's folder; a scene reads them by their plain names.
  // `use` gets the names uploaded (several at once: a .gltf and the buffers it names).
  const upload = (label, accept, id, use, multiple = false) => {
    const l = document.createElement('label');
    l.className = 'file';
    l.textContent = `${label} `;
    const input = document.createElement('input');
    input.type = 'file';
    input.accept = accept;
    input.id = id;
    input.multiple = multiple;
    input.addEventListener('change', async () => {
      const names = [];
      for (const file of input.files) {
        // The names the server takes: letters, digits, spaces, - _ and dots (not
        // leading, no '..'), so a glTF's buffers keep the names it gives them.
        const name = file.name.replace(/[^A-Za-z0-9._ -]/g, '_').replace(/\.\.+/g, '.').replace(/^[. ]+/, '');
        const r = await fetch(`/api/session/${studio.session}/upload/${encodeURIComponent(name)}`, { method: 'POST', body: file });
        if (!r.ok) {
          say('error', `upload of ${file.name} failed (${r.status}): ${await r.text()}`);
          return;
        }
        names.push(name);
      }
      if (names.length) use(names);
    });
    l.append(input);
    box.append(l);
  };
  const background = (path) => upload('Background image', 'image/png', 'background-upload', (names) =>
    setParam(path, { kind: 'image', path: names[0] }));
  if (phenomenon === 'flame' || phenomenon === 'sparkle') {
    background('render.background');
  } else if (phenomenon === 'aurora') {
    background('render.sky.background');
  } else if (phenomenon === 'snow') {
    // A glTF's buffers are uploaded with it (select them all); the mesh is the file
    // with a mesh extension.
    upload('Mesh (OBJ, GLB, glTF + buffers, DXF)', '.obj,.glb,.gltf,.bin,.dxf', 'mesh-upload', (names) => {
      const mesh = names.find((n) => /\.(obj|glb|gltf|dxf)$/i.test(n));
      // The mesh replaces the built-in scene (a scene names one or the other).
      if (mesh) setParam('geometry', { scale: (studio.scene.geometry || {}).scale ?? 1, mesh });
      else say('error', 'no mesh among the files: choose an .obj, .glb, .gltf or .dxf file (with the buffers a .gltf names)');
    }, true);
    background('render.background');
    const a = document.createElement('a');
    a.id = 'snow-glb';
    a.textContent = 'Download snow mesh (GLB)';
    a.href = `/api/session/${studio.session}/snow.glb`;
    a.download = 'snow.glb';
    box.append(a);
  }
}

function onScene(msg) {
  studio.generation = msg.generation;
  studio.lastFrame = -1; // no frame of this generation shown yet
  studio.scene = msg.scene;
  scenes[msg.phenomenon] = msg.scene;
  if (msg.phenomenon !== studio.phenomenon) {
    // A loaded file can switch the tab.
    studio.phenomenon = msg.phenomenon;
    for (const b of document.querySelectorAll('#tabs button')) {
      b.setAttribute('aria-selected', String(b.dataset.phenomenon === msg.phenomenon));
    }
    $('aurora-editor').hidden = msg.phenomenon !== 'aurora';
    $('wind-hint').hidden = msg.phenomenon !== 'flame';
    buildExtras(msg.phenomenon);
  }
  const controls = catalogue.controls[msg.phenomenon] || [];
  buildForm($('form'), controls, hello.featured[msg.phenomenon] || [], msg.scene, setParam);
  $('seed').value = msg.scene.scene.seed;
  // The frames to render follow the scene only when the phenomenon or its frame
  // count changed: a re-sent scene (a parameter, a re-opened tab) keeps what was typed.
  const framesKey = `${msg.phenomenon}:${msg.scene.scene.frames}`;
  if (studio.framesKey !== framesKey) {
    studio.framesKey = framesKey;
    $('final-frames').value = msg.scene.scene.frames;
  }
  const view = controls.find((c) => c.path === 'render.view');
  const toggle = $('view-toggle');
  toggle.replaceChildren();
  if (view && getPath(msg.scene, 'render.view') !== undefined) {
    const b = document.createElement('button');
    b.type = 'button';
    b.id = 'toggle-view';
    const current = getPath(msg.scene, 'render.view');
    const other = view.choices[(view.choices.indexOf(current) + 1) % view.choices.length];
    b.textContent = `View: ${current} → ${other}`;
    b.addEventListener('click', () => setParam('render.view', other));
    toggle.append(b);
  }
  if (msg.editor) editor.update(msg.editor);
}

async function onFrame(buffer) {
  const view = new DataView(buffer);
  const generation = view.getUint32(0, true);
  if (generation !== studio.generation) return; // stale: a change came after it
  const bitmap = await createImageBitmap(new Blob([new Uint8Array(buffer, 16)], { type: 'image/jpeg' }));
  if (generation !== studio.generation) return;
  if (preview.width !== bitmap.width || preview.height !== bitmap.height) {
    preview.width = bitmap.width;
    preview.height = bitmap.height;
  }
  ctx.drawImage(bitmap, 0, 0);
  studio.frames += 1;
  studio.lastFrame = view.getUint32(4, true);
  const now = performance.now();
  if (change && generation > change.generation) {
    studio.latencies.push(now - change.at);
    change = null;
  }
  shown.push(now);
  while (shown.length > 31) shown.shift();
  if (shown.length > 1) studio.fps = (1000 * (shown.length - 1)) / (shown[shown.length - 1] - shown[0]);
  $('fps').textContent = `${studio.fps.toFixed(1)} fps · frame ${studio.lastFrame}`;
}

function onCounters(msg) {
  studio.counters = msg;
  const c = msg.counters || {};
  const parts = [`step ${msg.step_ms.toFixed(1)} ms`, `render ${msg.render_ms.toFixed(1)} ms`];
  if (c.virtual_count != null) parts.unshift(`virtual ${c.virtual_count.toExponential(2)}`, `generated ${c.generated}`);
  else if (c.particles != null) parts.unshift(`particles ${c.particles}`);
  $('counters').textContent = parts.join(' · ');
}

function download(name, text) {
  const a = document.createElement('a');
  a.href = URL.createObjectURL(new Blob([text], { type: 'application/toml' }));
  a.download = name;
  document.body.append(a);
  a.click();
  a.remove();
}

function onMessage(msg) {
  switch (msg.type) {
    case 'hello':
      hello = msg;
      studio.session = msg.session;
      $('connection').textContent = `session ${msg.session.slice(0, 6)}`;
      buildTabs(msg.phenomena);
      selectTab(msg.phenomena.some((p) => p.name === location.hash.slice(1)) ? location.hash.slice(1) : 'aurora');
      break;
    case 'scene': onScene(msg); markIssues($('form'), []); break;
    case 'frame': onCounters(msg); break;
    case 'notice': say('notice', msg.message); break;
    case 'refused': say('refused', msg.message); break;
    case 'error':
      say('error', msg.message);
      markIssues($('form'), msg.issues);
      break;
    case 'saved':
      if (!msg.valid) say('error', `saved, but the scene is not valid yet: ${msg.problems.join('; ')}`);
      download(msg.name, msg.toml);
      break;
    case 'progress':
      $('final-progress').hidden = false;
      $('final-progress').max = msg.total;
      $('final-progress').value = msg.done;
      $('final-status').textContent = `${msg.done} / ${msg.total} frames`;
      break;
    case 'rendered':
      $('final-status').textContent = `done: ${msg.frames} frames in ${msg.dir}`;
      say('notice', `render final: ${msg.frames} frames written to ${msg.dir}`);
      break;
    case 'wind': break;
    default: say('error', `unknown message ${msg.type}`);
  }
}

function connect() {
  ws = new WebSocket(`ws://${location.host}/ws`);
  ws.binaryType = 'arraybuffer';
  ws.addEventListener('open', () => { $('connection').textContent = 'connected'; });
  ws.addEventListener('close', () => { $('connection').textContent = 'disconnected: reload the page'; });
  ws.addEventListener('message', (e) => {
    if (typeof e.data === 'string') onMessage(JSON.parse(e.data));
    else onFrame(e.data);
  });
}

// Flame: a drag on the preview sets the wind (the paper's §6), kept after release.
const WIND_PER_WIDTH = 4.0; // N/m³ for a drag across the whole preview
let drag = null;
let lastWind = 0;
preview.addEventListener('pointerdown', (e) => {
  if (studio.phenomenon !== 'flame') return;
  preview.setPointerCapture(e.pointerId);
  drag = { x: e.clientX, y: e.clientY };
});
preview.addEventListener('pointermove', (e) => {
  if (!drag) return;
  const now = performance.now();
  if (now - lastWind < 40) return;
  lastWind = now;
  sendWind(e);
});
preview.addEventListener('pointerup', (e) => {
  if (!drag) return;
  sendWind(e);
  drag = null;
});
preview.addEventListener('dblclick', () => {
  if (studio.phenomenon === 'flame') send({ type: 'wind', force: [0, 0, 0] });
});
function sendWind(e) {
  const r = preview.getBoundingClientRect();
  const fx = ((e.clientX - drag.x) / r.width) * WIND_PER_WIDTH;
  const fy = (-(e.clientY - drag.y) / r.width) * WIND_PER_WIDTH;
  studio.wind = [fx, fy, 0];
  send({ type: 'wind', force: [fx, fy, 0] });
}

// One tab per phenomenon the server has, in its registry's order.
function buildTabs(phenomena) {
  const nav = $('tabs');
  nav.replaceChildren();
  for (const p of phenomena) {
    const b = document.createElement('button');
    b.setAttribute('role', 'tab');
    b.dataset.phenomenon = p.name;
    b.title = p.about;
    b.textContent = p.name[0].toUpperCase() + p.name.slice(1);
    b.addEventListener('click', () => selectTab(p.name));
    nav.append(b);
  }
}
$('play').addEventListener('click', () => send({ type: 'play' }));
$('pause').addEventListener('click', () => send({ type: 'pause' }));
$('step').addEventListener('click', () => send({ type: 'step' }));
$('reset').addEventListener('click', () => sendChange({ type: 'reset' }));
$('seed').addEventListener('change', () => setParam('scene.seed', Number($('seed').value)));
$('builtin').addEventListener('change', () => sendChange({ type: 'builtin', name: $('builtin').value }));
$('save').addEventListener('click', () => send({ type: 'save' }));
$('load').addEventListener('change', async () => {
  const file = $('load').files[0];
  if (file) sendChange({ type: 'toml', text: await file.text(), name: file.name });
});
$('render-final').addEventListener('click', () => {
  $('final-status').textContent = 'starting…';
  send({ type: 'render_final', frames: Number($('final-frames').value), format: $('final-format').value });
});

fetch('/api/controls').then((r) => r.json()).then((c) => {
  catalogue = c;
  connect();
});
