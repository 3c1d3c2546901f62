// phenomena studio: one WebSocket per tab; the server simulates and renders, this page
// draws, controls and shows. Test hooks live on `window.studio`.
import { buildForm, markIssues, getPath, showValue } from './form.js';
import { AuroraEditor } from './aurora.js';

const $ = (id) => document.getElementById(id);
const studio = {
  session: null, phenomenon: null, generation: 0, scene: null, frames: 0, fps: 0,
  latencies: [], messages: [], counters: null, lastImage: null, editor: null,
  time: null, name: '', dirty: false, undo: 0, redo: 0, lastRender: null,
  shownFrames: [], // the frame numbers of the last 200 images shown (tests)
};
window.studio = studio;

const PRESETS_KEY = 'phenomena-studio-presets'; // this browser's own presets
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

// A parameter naming a file just uploaded: set again even when the name is the same.
function setFile(path, value) {
  sendChange({ type: 'set', path, value, reload: true });
}

// Messages: errors stay until the scene changes (they are about the scene before);
// notices fade after a few seconds.
function say(kind, text) {
  studio.messages.push({ kind, text });
  const box = $('messages');
  const d = document.createElement('div');
  d.className = kind;
  d.textContent = text;
  box.prepend(d);
  while (box.children.length > 4) box.lastChild.remove();
  if (kind === 'notice') setTimeout(() => d.remove(), 8000);
}

function clearMessages() {
  $('messages').replaceChildren();
}

const editor = new AuroraEditor({
  source: $('source-canvas'), target: $('target-canvas'), strip: $('keyframes'), tool: $('target-tool'),
  hint: $('editor-hint'), caption: $('target-caption'), clear: $('clear-shapes'),
  send: (m) => sendChange(m),
});
studio.editor = editor;

function userPresets() {
  try {
    return JSON.parse(localStorage.getItem(PRESETS_KEY) || '[]');
  } catch {
    return [];
  }
}

// The preset menu: the shipped scenes by their looks, then this browser's own.
function fillPresets(phenomenon) {
  const select = $('builtin');
  select.replaceChildren();
  const group = (label, items) => {
    if (!items.length) return;
    const g = document.createElement('optgroup');
    g.label = label;
    for (const [value, text] of items) {
      const o = document.createElement('option');
      o.value = value;
      o.textContent = text;
      g.append(o);
    }
    select.append(g);
  };
  group('Presets', hello.builtins.filter((x) => x.phenomenon === phenomenon).map((b) => [b.name, `${b.title} (${b.name})`]));
  group('Your presets', userPresets().filter((x) => x.phenomenon === phenomenon).map((u) => [`user:${u.name}`, u.name]));
  const edited = document.createElement('option');
  edited.value = '';
  edited.disabled = true;
  edited.textContent = '(this scene, edited or opened from a file)';
  select.append(edited);
}

// Show the preset the scene came from, or say it is its own.
function showPreset() {
  const select = $('builtin');
  const values = [...select.options].map((o) => o.value);
  const user = `user:${studio.name}`;
  select.value = !studio.dirty && values.includes(studio.name) ? studio.name : !studio.dirty && values.includes(user) ? user : '';
}

function markTab(phenomenon) {
  for (const b of document.querySelectorAll('#tabs button')) {
    b.setAttribute('aria-selected', String(b.dataset.phenomenon === phenomenon));
  }
  $('aurora-editor').hidden = phenomenon !== 'aurora';
  $('wind-hint').hidden = phenomenon !== 'flame';
  fillPresets(phenomenon);
  const formats = $('final-format');
  formats.replaceChildren();
  for (const f of hello.phenomena.find((p) => p.name === phenomenon).formats) {
    const o = document.createElement('option');
    o.value = f;
    o.textContent = f;
    formats.append(o);
  }
  $('flipbook-options').hidden = true;
  buildExtras(phenomenon);
}

// A tab keeps its scene, simulation and frame on the server while another is shown.
function selectTab(phenomenon) {
  studio.phenomenon = phenomenon;
  markTab(phenomenon);
  $('counters').textContent = '';
  sendChange({ type: 'tab', phenomenon });
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
    setFile(path, { kind: 'image', path: names[0] }));
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
      if (mesh) setFile('geometry', { scale: (studio.scene.geometry || {}).scale ?? 1, mesh });
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
  // A new generation is an accepted change: the messages about the scene before go.
  // (A refused change re-sends the same generation, and its error stays.)
  if (msg.generation !== studio.generation) {
    clearMessages();
    studio.shownFrames = [];
  }
  studio.generation = msg.generation;
  studio.lastFrame = -1; // no frame of this generation shown yet
  studio.scene = msg.scene;
  if (msg.phenomenon !== studio.phenomenon) {
    // A loaded file can switch the tab.
    studio.phenomenon = msg.phenomenon;
    markTab(msg.phenomenon);
  }
  $('editor-hint').textContent = '';
  showScene(msg);
  const controls = catalogue.controls[msg.phenomenon] || [];
  buildForm($('form'), controls, hello.featured[msg.phenomenon] || [], msg.scene, setParam);
  $('seed').value = msg.scene.scene.seed;
  // The frames to render follow the scene only when the phenomenon or its frame
  // count changed: a re-sent scene (a parameter, a re-opened tab) keeps what was typed.
  const framesKey = `${msg.phenomenon}:${msg.scene.scene.frames}`;
  if (studio.framesKey !== framesKey) {
    studio.framesKey = framesKey;
    $('final-first').value = 0;
    $('final-last').value = msg.scene.scene.frames - 1;
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

// Name, dirty marker and undo/redo counts.
function showScene(msg) {
  if (msg.name !== undefined) studio.name = msg.name;
  if (msg.dirty !== undefined) studio.dirty = msg.dirty;
  if (msg.undo !== undefined) studio.undo = msg.undo;
  if (msg.redo !== undefined) studio.redo = msg.redo;
  const name = $('scene-name');
  name.textContent = studio.name;
  name.classList.toggle('dirty', studio.dirty);
  name.title = studio.dirty ? `${studio.name}: changed since it was opened or saved` : studio.name;
  $('save-name').placeholder = studio.name;
  $('undo').disabled = studio.undo === 0;
  $('redo').disabled = studio.redo === 0;
  showPreset();
}

// Where the tab is in time (the server's `time` messages).
let scrubbing = false;
function onTime(msg) {
  const status = $('time-status');
  if (msg.catching_up) {
    status.textContent = `simulating: frame ${msg.catching_up.frame} of ${msg.catching_up.target}…`;
    return;
  }
  if (msg.generation !== undefined && msg.generation < studio.generation) return;
  studio.time = msg;
  if (msg.change) studio.lastChange = { generation: msg.generation, change: msg.change, frame: msg.frame };
  const scrubber = $('scrubber');
  scrubber.max = String(msg.length - 1);
  if (!scrubbing) scrubber.value = String(msg.target ?? msg.frame);
  $('loop').checked = msg.looping;
  $('play').setAttribute('aria-pressed', String(msg.playing));
  $('pause').setAttribute('aria-pressed', String(!msg.playing));
  showFrame(msg.target ?? msg.frame, msg.length);
  if (msg.change === 'render') status.textContent = `only how frames are drawn changed: frame ${msg.frame} drawn again from the running simulation`;
  else if (msg.change === 'simulation' && msg.frame > 0) status.textContent = `the simulation changed: simulating again from frame 0 to frame ${msg.frame}`;
  else if (msg.target == null && status.textContent.startsWith('simulating')) status.textContent = '';
  $('time-info').textContent = `${msg.playing ? 'playing' : 'paused'} at ${msg.fps.toFixed(0)} fps · states kept every ${msg.kept_every} frames (${(msg.kept_bytes / 1048576).toFixed(1)} MiB)`;
}

function showFrame(frame, length) {
  $('frame-readout').textContent = `${frame} / ${length - 1}`;
}

// Images are decoded as they come; one that finishes decoding after a later one is
// dropped, so frames are drawn in the order they were sent.
let received = 0;
let drawn = 0;
async function onFrame(buffer) {
  const view = new DataView(buffer);
  const generation = view.getUint32(0, true);
  if (generation !== studio.generation) return; // stale: a change came after it
  const seq = ++received;
  const bitmap = await createImageBitmap(new Blob([new Uint8Array(buffer, 16)], { type: 'image/jpeg' }));
  if (generation !== studio.generation || seq < drawn) return;
  drawn = seq;
  if (preview.width !== bitmap.width || preview.height !== bitmap.height) {
    preview.width = bitmap.width;
    preview.height = bitmap.height;
  }
  ctx.drawImage(bitmap, 0, 0);
  studio.frames += 1;
  studio.lastFrame = view.getUint32(4, true);
  studio.shownFrames.push(studio.lastFrame);
  if (studio.shownFrames.length > 200) studio.shownFrames.shift();
  if (!scrubbing) $('scrubber').value = String(studio.lastFrame);
  if (studio.time) showFrame(studio.lastFrame, studio.time.length);
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
  // A snow scene steps its next frame beside the render (within render_ms).
  if (msg.ahead_ms != null) parts.push(`next step ${msg.ahead_ms.toFixed(1)} ms beside it`);
  if (c.virtual_count != null) parts.unshift(`virtual ${c.virtual_count.toExponential(2)}`, `generated ${c.generated}`);
  else if (c.particles != null) parts.unshift(`particles now ${c.particles.toLocaleString('en')}`);
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
      // The studio opens on the campfire at dusk (the flame's first preset).
      selectTab(msg.phenomena.some((p) => p.name === location.hash.slice(1)) ? location.hash.slice(1) : 'flame');
      break;
    case 'scene': onScene(msg); markIssues($('form'), []); break;
    case 'time': onTime(msg); break;
    case 'frame': onCounters(msg); break;
    case 'notice': say('notice', msg.message); break;
    case 'refused': say('refused', msg.message); break;
    case 'error':
      say('error', msg.message);
      markIssues($('form'), msg.issues);
      break;
    case 'saved':
      if (!msg.valid) say('error', `saved, but the scene is not valid yet: ${msg.problems.join('; ')}`);
      showScene({ name: msg.scene_name, dirty: msg.dirty });
      download(msg.name, msg.toml);
      break;
    case 'progress':
      $('final-progress').hidden = false;
      $('final-progress').max = msg.total;
      $('final-progress').value = msg.done;
      $('final-status').textContent = msg.pre_roll
        ? `pre-roll: simulating frame ${msg.done - 1} (frames ${msg.first} to ${msg.total - 1} are written)`
        : `frame ${msg.done - 1} of ${msg.first}–${msg.total - 1} written to ${msg.dir}`;
      break;
    case 'rendered':
      studio.lastRender = msg;
      $('final-status').textContent = `done: frames ${msg.first} to ${msg.last} in ${msg.dir} (${msg.files.join(', ')})`;
      say('notice', `render final: ${msg.frames} frames written to ${msg.dir}`);
      break;
    case 'wind':
      // The wind dragged on the preview is the scene's now: the control shows it, and
      // a preset kept from here keeps it.
      showValue($('form'), `${msg.path}.force_n_m3`, msg.force);
      if (studio.scene && studio.scene.flame) studio.scene.flame.wind = { ...(studio.scene.flame.wind || {}), force_n_m3: msg.force };
      showScene({ dirty: msg.dirty, undo: msg.undo, redo: 0 });
      break;
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
  drag = { x: e.clientX, y: e.clientY, start: true };
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
  if (studio.phenomenon === 'flame') send({ type: 'wind', force: [0, 0, 0], start: true });
});
function sendWind(e) {
  const r = preview.getBoundingClientRect();
  const fx = ((e.clientX - drag.x) / r.width) * WIND_PER_WIDTH;
  const fy = (-(e.clientY - drag.y) / r.width) * WIND_PER_WIDTH;
  studio.wind = [fx, fy, 0];
  send({ type: 'wind', force: [fx, fy, 0], start: drag.start });
  drag.start = false;
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
$('step-back').addEventListener('click', () => seek(shownFrame() - 1));
$('reset').addEventListener('click', () => send({ type: 'reset' }));
$('undo').addEventListener('click', () => sendChange({ type: 'undo' }));
$('redo').addEventListener('click', () => sendChange({ type: 'redo' }));
$('loop').addEventListener('change', () => send({ type: 'loop', on: $('loop').checked }));
$('seed').addEventListener('change', () => setParam('scene.seed', Number($('seed').value)));

// The frame on screen: while paused the server's word (an image may still be on its
// way), while playing the last image drawn.
function shownFrame() {
  const t = studio.time;
  if (t && !t.playing) return t.target ?? t.frame;
  return Math.max(0, studio.lastFrame ?? 0);
}
function seek(frame) {
  if (frame < 0) return;
  send({ type: 'seek', frame });
}
// The scrubber: while dragged it shows where it is and asks for that frame.
const scrubber = $('scrubber');
// While dragged, at most one seek every 60 ms (the last position is always sent).
let seekTimer = null;
let lastSeekAt = 0;
scrubber.addEventListener('input', () => {
  scrubbing = true;
  showFrame(Number(scrubber.value), Number(scrubber.max) + 1);
  clearTimeout(seekTimer);
  const wait = Math.max(0, 60 - (performance.now() - lastSeekAt));
  seekTimer = setTimeout(() => {
    lastSeekAt = performance.now();
    seek(Number(scrubber.value));
  }, wait);
});
scrubber.addEventListener('change', () => { scrubbing = false; });

// Keyboard: Space play/pause, arrows step, Home to the start, Ctrl+Z / Ctrl+Shift+Z
// (or Ctrl+Y) undo and redo. Space and the arrows act only where they mean nothing
// else (the page, the preview, the scrubber): a focused checkbox, button or menu keeps
// its own keys; Ctrl+Z in a text or number field is the field's own undo.
document.addEventListener('keydown', (e) => {
  const t = e.target;
  const field = t instanceof HTMLTextAreaElement
    || (t instanceof HTMLInputElement && !['checkbox', 'radio', 'range', 'button', 'file'].includes(t.type));
  const ctrl = e.ctrlKey || e.metaKey;
  if (ctrl && !e.altKey && (e.key === 'z' || e.key === 'Z' || e.key === 'y')) {
    if (field) return;
    e.preventDefault();
    sendChange({ type: e.key === 'y' || e.shiftKey ? 'redo' : 'undo' });
    return;
  }
  const free = t === document.body || t === document.documentElement || t === preview || t === scrubber;
  if (!free || ctrl || e.altKey) return;
  if (e.key === ' ') {
    e.preventDefault();
    send({ type: studio.time && studio.time.playing ? 'pause' : 'play' });
  } else if (e.key === 'ArrowRight') {
    e.preventDefault();
    send({ type: 'step' });
  } else if (e.key === 'ArrowLeft') {
    e.preventDefault();
    seek(shownFrame() - 1);
  } else if (e.key === 'Home') {
    e.preventDefault();
    seek(0);
  }
});

$('builtin').addEventListener('change', () => {
  const v = $('builtin').value;
  if (v.startsWith('user:')) {
    const p = userPresets().find((u) => u.phenomenon === studio.phenomenon && u.name === v.slice(5));
    if (p) sendChange({ type: 'scene', phenomenon: p.phenomenon, scene: p.scene, name: p.name });
  } else if (v) {
    sendChange({ type: 'builtin', name: v });
  }
});
$('save').addEventListener('click', () => {
  const name = $('save-name').value.trim();
  send(name ? { type: 'save', name } : { type: 'save' });
});
$('keep-preset').addEventListener('click', () => {
  const name = $('save-name').value.trim() || studio.name;
  if (!name || !studio.scene) return;
  const kept = userPresets().filter((u) => !(u.phenomenon === studio.phenomenon && u.name === name));
  kept.push({ name, phenomenon: studio.phenomenon, scene: studio.scene });
  localStorage.setItem(PRESETS_KEY, JSON.stringify(kept));
  fillPresets(studio.phenomenon);
  $('builtin').value = `user:${name}`;
  say('notice', `kept "${name}" in this browser's presets`);
});
$('load').addEventListener('change', async () => {
  const file = $('load').files[0];
  if (file) sendChange({ type: 'toml', text: await file.text(), name: file.name });
});
$('final-format').addEventListener('change', () => {
  $('flipbook-options').hidden = $('final-format').value !== 'flipbook';
});
$('final-here').addEventListener('click', () => { $('final-first').value = shownFrame(); });
$('render-final').addEventListener('click', () => {
  $('final-status').textContent = 'starting…';
  $('final-progress').value = 0;
  const format = $('final-format').value;
  const msg = { type: 'render_final', first: Number($('final-first').value), last: Number($('final-last').value), format };
  if (format === 'flipbook') {
    Object.assign(msg, { crop: $('final-crop').checked, pot: $('final-pot').checked, loop_frames: Number($('final-loop').value), alpha: $('final-alpha').value });
  }
  send(msg);
});

// The preview's size follows its frame (drag the corner): the new size is asked for
// once the drag rests; only how frames are drawn changes, so the frame stays.
let resizeTimer = null;
new ResizeObserver(([entry]) => {
  const { width, height } = entry.contentRect;
  const w = Math.max(16, Math.min(1920, Math.round(width / 8) * 8));
  const h = Math.max(16, Math.min(1920, Math.round(height / 8) * 8));
  if (!hello || (w === preview.width && h === preview.height)) return;
  clearTimeout(resizeTimer);
  resizeTimer = setTimeout(() => sendChange({ type: 'preview', width: w, height: h }), 300);
}).observe($('preview-wrap'));

fetch('/api/controls').then((r) => r.json()).then((c) => {
  catalogue = c;
  connect();
});
