// The aurora editor (thesis §3.1, Figs 3.1-3.3): a source canvas and a target canvas.
// A drag draws a sheet (the server resamples it to n control points by eq 2.1 and
// refuses strokes that cross); the target canvas shows the source behind it and
// highlights the sheet the next stroke fills; split a segment or merge two end points
// with a click; a keyframe strip adds, selects, moves and deletes target shapes.

const SOURCE_COLOUR = '#7fc4ff';
const TARGET_COLOUR = '#a5e887';
const NEXT_COLOUR = '#ffd166';

export class AuroraEditor {
  constructor({ source, target, strip, tool, hint, caption, clear, send }) {
    Object.assign(this, { source, target, strip, tool, hint, caption, send });
    this.state = null;
    this.selected = 1;
    this.mergeFirst = null;
    this.stroke = null;
    for (const [canvas, which] of [[source, 'source'], [target, 'target']]) {
      canvas.addEventListener('pointerdown', (e) => this.down(e, which));
      canvas.addEventListener('pointermove', (e) => this.move(e, which));
      canvas.addEventListener('pointerup', (e) => this.up(e, which));
    }
    clear.addEventListener('click', () => this.send({ type: 'aurora', op: 'clear' }));
    tool.addEventListener('change', () => {
      this.mergeFirst = null;
      this.draw();
    });
  }

  update(editor) {
    this.state = editor;
    const last = editor.keyframes.length - 1;
    this.selected = Math.min(Math.max(this.selected, 1), last);
    this.mergeFirst = null;
    // The strip's buttons are replaced only when what they show changed: a click that
    // lands while an unchanged state arrives must not hit a button being replaced.
    if (this.stripSignature() !== this.builtSignature) this.buildStrip();
    this.draw();
  }

  stripSignature() {
    return JSON.stringify([this.state.keyframes.map((kf) => kf.frame), this.selected]);
  }

  mapping(canvas) {
    const [w, h] = this.state.plane_km;
    const s = Math.min(canvas.width / w, canvas.height / h);
    return { s, ox: (canvas.width - w * s) / 2, oy: (canvas.height - h * s) / 2 };
  }

  toPx(canvas, p) {
    const m = this.mapping(canvas);
    return [m.ox + p[0] * m.s, m.oy + p[1] * m.s];
  }

  toKm(canvas, e) {
    const r = canvas.getBoundingClientRect();
    const x = ((e.clientX - r.left) * canvas.width) / r.width;
    const y = ((e.clientY - r.top) * canvas.height) / r.height;
    const m = this.mapping(canvas);
    const [w, h] = this.state.plane_km;
    return [Math.min(Math.max((x - m.ox) / m.s, 0), w), Math.min(Math.max((y - m.oy) / m.s, 0), h)];
  }

  keyframeOf(which) {
    return which === 'source' ? 0 : this.selected;
  }

  down(e, which) {
    if (!this.state) return;
    const k = this.keyframeOf(which);
    if (which === 'target' && this.tool.value !== 'draw') {
      this.pick(this.toKm(this.target, e), k);
      return;
    }
    e.target.setPointerCapture(e.pointerId);
    this.stroke = { which, points: [this.toKm(e.target, e)] };
  }

  move(e, which) {
    if (!this.stroke || this.stroke.which !== which) return;
    const p = this.toKm(e.target, e);
    const q = this.stroke.points[this.stroke.points.length - 1];
    if (Math.hypot(p[0] - q[0], p[1] - q[1]) > 0.5) this.stroke.points.push(p);
    this.draw();
  }

  up(e, which) {
    if (!this.stroke || this.stroke.which !== which) return;
    const { points } = this.stroke;
    this.stroke = null;
    if (points.length >= 2) {
      this.send({ type: 'aurora', op: 'stroke', keyframe: this.keyframeOf(which), points });
    }
    this.draw();
  }

  // Split: the segment nearest the click; merge: the nearest end point, twice.
  pick(p, k) {
    const shape = this.state.keyframes[k].shape;
    if (!this.state.built) {
      this.hint.textContent = 'finish the shapes first: split and merge need a complete animation';
      return;
    }
    const m = this.mapping(this.target);
    const tolerance = 10 / m.s; // 10 pixels, in km
    if (this.tool.value === 'split') {
      let best = null;
      shape.next.forEach((j, i) => {
        if (j == null) return;
        const d = segmentDistance(p, shape.points[i], shape.points[j]);
        if (d < tolerance && (!best || d < best.d)) best = { d, i };
      });
      if (!best) {
        this.hint.textContent = 'click on a segment to split it';
        return;
      }
      this.send({ type: 'aurora', op: 'split', keyframe: k, sheet: shape.sheet[best.i], point: shape.index[best.i] });
    } else {
      const links = new Array(shape.points.length).fill(0);
      shape.next.forEach((j, i) => {
        if (j != null) {
          links[i] += 1;
          links[j] += 1;
        }
      });
      let best = null;
      shape.points.forEach((q, i) => {
        if (links[i] !== 1) return;
        const d = Math.hypot(p[0] - q[0], p[1] - q[1]);
        if (d < tolerance && (!best || d < best.d)) best = { d, i };
      });
      if (!best) {
        this.hint.textContent = 'click on an end point of a sheet';
        return;
      }
      const ref = { sheet: shape.sheet[best.i], point: shape.index[best.i] };
      if (!this.mergeFirst) {
        this.mergeFirst = { ref, i: best.i };
        this.hint.textContent = 'now click the end point to join it to';
        this.draw();
      } else {
        this.send({ type: 'aurora', op: 'merge', keyframe: k, a: this.mergeFirst.ref, b: ref });
        this.mergeFirst = null;
      }
    }
  }

  buildStrip() {
    const kfs = this.state.keyframes;
    this.builtSignature = this.stripSignature();
    this.strip.replaceChildren();
    const label = document.createElement('span');
    label.className = 'hint';
    label.textContent = 'Keyframes:';
    this.strip.append(label);
    kfs.forEach((kf, k) => {
      const b = document.createElement('button');
      b.type = 'button';
      b.textContent = k === 0 ? `source · f${kf.frame}` : `${k} · f${kf.frame}`;
      b.dataset.keyframe = k;
      if (k === this.selected) b.classList.add('selected');
      if (k > 0) b.addEventListener('click', () => {
        this.selected = k;
        this.buildStrip();
        this.draw();
      });
      else b.disabled = true;
      this.strip.append(b);
    });
    const frame = document.createElement('input');
    frame.type = 'number';
    frame.min = 1;
    frame.step = 1;
    frame.id = 'keyframe-frame';
    frame.value = kfs[this.selected].frame;
    frame.title = 'frame of the selected keyframe';
    frame.addEventListener('change', () =>
      this.send({ type: 'aurora', op: 'move_keyframe', keyframe: this.selected, frame: Number(frame.value) }));
    const add = document.createElement('button');
    add.type = 'button';
    add.id = 'add-keyframe';
    add.textContent = 'Add keyframe';
    add.addEventListener('click', () => {
      this.selected = kfs.length;
      this.send({ type: 'aurora', op: 'add_keyframe', frame: kfs[kfs.length - 1].frame + 60 });
    });
    const del = document.createElement('button');
    del.type = 'button';
    del.id = 'delete-keyframe';
    del.textContent = 'Delete keyframe';
    del.addEventListener('click', () => this.send({ type: 'aurora', op: 'delete_keyframe', keyframe: this.selected }));
    const at = document.createElement('label');
    at.textContent = 'at frame ';
    at.append(frame);
    this.strip.append(at, add, del);
  }

  draw() {
    if (!this.state) return;
    const kfs = this.state.keyframes;
    const k = this.selected;
    const next = kfs[k].next_sheet;
    this.caption.textContent = next == null
      ? `Target shape (keyframe ${k}, frame ${kfs[k].frame}): every sheet drawn`
      : `Target shape (keyframe ${k}, frame ${kfs[k].frame}): drag to draw sheet ${next} (highlighted)`;
    for (const [canvas, which] of [[this.source, 'source'], [this.target, 'target']]) {
      const g = canvas.getContext('2d');
      g.fillStyle = '#05080c';
      g.fillRect(0, 0, canvas.width, canvas.height);
      const m = this.mapping(canvas);
      g.strokeStyle = '#222a33';
      g.strokeRect(m.ox, m.oy, this.state.plane_km[0] * m.s, this.state.plane_km[1] * m.s);
      if (which === 'source') {
        this.drawShape(g, canvas, kfs[0], SOURCE_COLOUR, 1, null);
      } else {
        this.drawShape(g, canvas, kfs[0], SOURCE_COLOUR, 0.25, null);
        this.drawShape(g, canvas, kfs[k], TARGET_COLOUR, 1, next);
      }
      if (this.stroke && this.stroke.which === which) {
        g.strokeStyle = '#ffffff';
        g.lineWidth = 1.5;
        g.beginPath();
        this.stroke.points.forEach((p, i) => {
          const [x, y] = this.toPx(canvas, p);
          if (i === 0) g.moveTo(x, y);
          else g.lineTo(x, y);
        });
        g.stroke();
      }
    }
  }

  drawShape(g, canvas, kf, colour, alpha, highlight) {
    const { shape, drawn } = kf;
    g.save();
    g.globalAlpha = alpha;
    shape.next.forEach((j, i) => {
      if (j == null) return;
      const s = shape.sheet[i];
      const placeholder = drawn && drawn[s] === false;
      g.strokeStyle = s === highlight ? NEXT_COLOUR : colour;
      g.lineWidth = s === highlight ? 3 : 1.5;
      g.setLineDash(placeholder ? [4, 4] : []);
      const [x0, y0] = this.toPx(canvas, shape.points[i]);
      const [x1, y1] = this.toPx(canvas, shape.points[j]);
      g.beginPath();
      g.moveTo(x0, y0);
      g.lineTo(x1, y1);
      g.stroke();
    });
    g.setLineDash([]);
    shape.points.forEach((p, i) => {
      const [x, y] = this.toPx(canvas, p);
      const picked = this.mergeFirst && canvas === this.target && this.mergeFirst.i === i && alpha === 1;
      g.fillStyle = picked ? '#ff5c8a' : shape.sheet[i] === highlight ? NEXT_COLOUR : colour;
      g.beginPath();
      g.arc(x, y, picked ? 5 : 2.5, 0, 2 * Math.PI);
      g.fill();
    });
    g.restore();
  }
}

function segmentDistance(p, a, b) {
  const [dx, dy] = [b[0] - a[0], b[1] - a[1]];
  const len2 = dx * dx + dy * dy;
  const t = len2 > 0 ? Math.min(Math.max(((p[0] - a[0]) * dx + (p[1] - a[1]) * dy) / len2, 0), 1) : 0;
  return Math.hypot(p[0] - (a[0] + t * dx), p[1] - (a[1] + t * dy));
}
