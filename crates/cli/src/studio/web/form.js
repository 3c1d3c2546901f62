// Parameter controls, generated from the server's catalogue (/api/controls): every
// number, switch, choice and vector of a scene, with its unit (from the field name)
// and the range the scene's own validation accepts.

// Field-name suffixes and their units, longest first.
const UNITS = [
  ['_deg_per_frame', '°/frame'], ['_deg_per_s', '°/s'], ['_m_s2_per_k', 'm/s² per K'],
  ['_kg_m3', 'kg/m³'], ['_m2_s2', 'm²/s²'], ['_n_m3', 'N/m³'], ['_cm_per_h', 'cm/h'],
  ['_m_per_s', 'm/s'], ['_km_s', 'km/s'], ['_m_s', 'm/s'], ['_per_s', '1/s'], ['_f_m', 'F/m'],
  ['_hz', 'Hz'], ['_kev', 'keV'], ['_km', 'km'], ['_deg', '°'], ['_kg', 'kg'], ['_nm', 'nm'],
  ['_ev', 'stops'], ['_m', 'm'], ['_s', 's'], ['_k', 'K'], ['_h', 'h'], ['_t', 'T'], ['_c', 'C'],
];

export function labelOf(path) {
  const key = path.split('.').pop();
  for (const [suffix, unit] of UNITS) {
    if (key.endsWith(suffix) && key.length > suffix.length) {
      return { name: key.slice(0, -suffix.length).replaceAll('_', ' '), unit };
    }
  }
  return { name: key.replaceAll('_', ' '), unit: '' };
}

export function getPath(obj, path) {
  return path.split('.').reduce((o, k) => (o == null ? undefined : o[k]), obj);
}

// Build the form into `root`. `send(path, value)` is called on every change.
// Sections the artist opened stay open when the form is built again (after every
// change).
export function buildForm(root, controls, featured, scene, send) {
  const open = new Set([...root.querySelectorAll('details[open] > summary')].map((s) => s.textContent));
  const focused = document.activeElement && root.contains(document.activeElement) ? document.activeElement.id : null;
  root.replaceChildren();
  const present = controls.filter((c) => getPath(scene, c.path) !== undefined);
  const top = document.createElement('div');
  top.className = 'featured';
  for (const path of featured) {
    const c = present.find((x) => x.path === path);
    if (c) top.append(controlElement(c, getPath(scene, c.path), send, true));
  }
  root.append(top);
  const groups = new Map();
  for (const c of present) {
    if (featured.includes(c.path)) continue;
    const parts = c.path.split('.');
    const group = parts.length > 2 ? parts.slice(0, 2).join('.') : parts[0];
    if (!groups.has(group)) groups.set(group, []);
    groups.get(group).push(c);
  }
  for (const [group, list] of groups) {
    const d = document.createElement('details');
    const s = document.createElement('summary');
    s.textContent = `[${group}]`;
    d.append(s);
    for (const c of list) d.append(controlElement(c, getPath(scene, c.path), send));
    d.open = open.has(s.textContent);
    root.append(d);
  }
  if (focused) document.getElementById(focused)?.focus();
}

// A number as people write it: f32 values come as the nearest double
// (0.0024999999441206455); seven significant digits give the f32 back.
export function shown(x) {
  return typeof x === 'number' && Number.isFinite(x) && !Number.isInteger(x) ? Number(x.toPrecision(7)) : x;
}

// The id of the input of the control at `path`.
export function inputId(path) {
  return `ctl-${path.replace(/[^A-Za-z0-9_-]/g, '-')}`;
}

// Featured controls stand outside their table, so their label names the table too
// (`shimmer enabled`, `light azimuth`). Each input is tied to its label (`for`) and to
// its valid range (`aria-describedby`), so assistive technology and tests find it by
// name.
function controlElement(c, value, send, featured = false) {
  const row = document.createElement('div');
  row.className = 'control';
  row.dataset.path = c.path;
  const label = labelOf(c.path);
  const unit = label.unit;
  const parents = c.path.split('.').slice(1, -1).map((p) => p.replaceAll('_', ' '));
  const name = featured && parents.length ? `${parents.join(' ')} ${label.name}` : label.name;
  const id = inputId(c.path);
  const title = document.createElement('label');
  title.className = 'name';
  title.textContent = name;
  title.title = c.path;
  title.htmlFor = id;
  row.append(title);
  const box = document.createElement('span');
  let input;
  if (c.kind === 'bool') {
    input = document.createElement('input');
    input.type = 'checkbox';
    input.checked = !!value;
    input.addEventListener('change', () => send(c.path, input.checked));
    box.append(input);
  } else if (c.kind === 'choice') {
    input = document.createElement('select');
    for (const choice of c.choices) {
      const o = document.createElement('option');
      o.value = choice;
      o.textContent = choice;
      input.append(o);
    }
    input.value = value;
    input.addEventListener('change', () => send(c.path, input.value));
    box.append(input);
  } else if (c.kind === 'vector') {
    box.className = 'vector';
    const axes = ['x', 'y', 'z', 'w'];
    const inputs = value.map((x, i) => {
      const e = numberInput(c, x, false);
      e.setAttribute('aria-label', `${name} ${axes[i] ?? i}`);
      box.append(e);
      return e;
    });
    for (const i of inputs) {
      i.addEventListener('change', () => send(c.path, inputs.map((e) => Number(e.value))));
    }
    input = inputs[0];
  } else if (c.kind === 'text') {
    input = document.createElement('input');
    input.type = 'text';
    input.value = value;
    input.addEventListener('change', () => send(c.path, input.value));
    box.append(input);
  } else {
    input = numberInput(c, value, c.kind === 'integer');
    input.addEventListener('change', () => {
      if (input.value === '') return;
      send(c.path, Number(input.value));
    });
    box.append(input);
  }
  if (input) input.id = id;
  if (unit) {
    const u = document.createElement('span');
    u.className = 'unit';
    u.textContent = ` ${unit}`;
    box.append(u);
  }
  row.append(box);
  if (c.valid) {
    const v = document.createElement('span');
    v.className = 'valid';
    v.id = `${id}-valid`;
    v.textContent = `valid: ${c.valid}`;
    row.append(v);
    for (const i of box.querySelectorAll('input, select')) i.setAttribute('aria-describedby', v.id);
  }
  return row;
}

function numberInput(c, value, integer) {
  const i = document.createElement('input');
  i.type = 'number';
  i.step = integer ? '1' : 'any';
  if (c.min != null && c.kind !== 'vector') i.min = c.min;
  if (c.max != null && c.kind !== 'vector') i.max = c.max;
  i.value = shown(value);
  return i;
}

// Show `value` in the control at `path` without rebuilding the form (a live change
// such as the flame's wind).
export function showValue(root, path, value) {
  const row = root.querySelector(`.control[data-path="${CSS.escape(path)}"]`);
  if (!row) return;
  const inputs = [...row.querySelectorAll('input')];
  if (Array.isArray(value)) inputs.forEach((i, k) => { i.value = shown(value[k]); });
  else if (inputs[0]) inputs[0].value = shown(value);
}

// Mark the controls the server refused (issues carry field paths).
export function markIssues(root, issues) {
  for (const row of root.querySelectorAll('.control.bad')) row.classList.remove('bad');
  for (const issue of issues || []) {
    for (const row of root.querySelectorAll('.control')) {
      const path = row.dataset.path;
      if (path === issue.field || path.endsWith(`.${issue.field}`)) {
        row.classList.add('bad');
        row.title = issue.message;
      }
    }
  }
}
