(function () {
  "use strict";
  const D = JSON.parse(document.getElementById("explore-data").textContent);
  const n = D.hit.length;
  const PAL = ["#1f77b4", "#d62728", "#2ca02c", "#ff7f0e", "#9467bd", "#8c564b", "#e377c2",
    "#17becf", "#bcbd22", "#7f7f7f"];
  const $ = (id) => document.getElementById(id);
  const col = {};
  for (const c of D.columns) col[c.name] = c;
  // Energy spans decades: plotted as its logarithm.
  const value = (name) => {
    if (name === "loc_x") return D.loc_x;
    if (name === "loc_y") return D.loc_y;
    const c = col[name];
    if (name === "energy_eu") return c.v.map((v) => (v > 0 ? Math.log10(v) : null));
    return c.v;
  };
  const label = (name) => name === "loc_x" ? "source x (m)" : name === "loc_y" ? "source y (m)"
    : name === "energy_eu" ? "log10 energy (eu)" : col[name] ? col[name].label : name;
  const has = (name) => { const v = value(name); return !!v && v.some((x) => x !== null); };
  const mask = new Uint8Array(n);
  let selecting = false;
  // Colour by the SOM class when the run has one, else the first colouring.
  let coloring = Math.max(0, D.colorings.findIndex((c) => c.name === "SOM class"));
  const emb = new Set(D.embedded);
  // The rows a point stands for.
  const weight = (i) => (D.w ? D.w[i] : D.stride);
  const keyOf = (i) => D.experiments[D.exp[i]] + "|" + D.ch[i] + "|" + D.hit[i];
  const classOf = (i) => {
    const c = D.colorings[coloring];
    if (!c) return null;
    const k = c.of[i];
    return k === null ? null : c.classes[k];
  };
  const colorOf = (i) => {
    const c = D.colorings[coloring];
    const k = c ? c.of[i] : null;
    return k === null || k === undefined ? "#999" : PAL[k % PAL.length];
  };

  class Chart {
    constructor(title, xName, yName, opts) {
      this.title = title; this.xName = xName; this.yName = yName;
      this.opts = opts || {};
      this.fig = document.createElement("figure");
      this.canvas = document.createElement("canvas");
      this.canvas.width = 880; this.canvas.height = 320;
      this.canvas.tabIndex = 0;
      this.canvas.dataset.chart = title;
      this.fig.appendChild(this.canvas);
      const cap = document.createElement("figcaption");
      cap.textContent = title;
      this.fig.appendChild(cap);
      $("ex-charts").appendChild(this.fig);
      this.view = null; this.drawn = false; this.points = 0;
      this.m = { l: 78, r: 16, t: 12, b: 40 };
      this.listen();
    }
    xs() { return value(this.xName); }
    ys() { return value(this.yName); }
    full() {
      if (this.opts.cumulative) return this.fullCumulative();
      const x = this.xs(), y = this.ys();
      let x0 = Infinity, x1 = -Infinity, y0 = Infinity, y1 = -Infinity;
      for (let i = 0; i < n; i++) {
        if (x[i] === null || y[i] === null) continue;
        x0 = Math.min(x0, x[i]); x1 = Math.max(x1, x[i]);
        y0 = Math.min(y0, y[i]); y1 = Math.max(y1, y[i]);
      }
      if (!isFinite(x0)) return [0, 1, 0, 1];
      const px = (x1 - x0) * 0.03 || 1, py = (y1 - y0) * 0.05 || 1;
      return [x0 - px, x1 + px, y0 - py, y1 + py];
    }
    // Time span, and 0 to the largest class's count.
    fullCumulative() {
      const t = this.xs(), c = D.colorings[coloring];
      let t0 = Infinity, t1 = -Infinity;
      const count = new Array(c ? c.classes.length : 0).fill(0);
      for (let i = 0; i < n; i++) {
        if (t[i] === null || (selecting && !mask[i])) continue;
        t0 = Math.min(t0, t[i]); t1 = Math.max(t1, t[i]);
        const k = c ? c.of[i] : null;
        if (k !== null) count[k] += weight(i);
      }
      if (!isFinite(t0)) return [0, 1, 0, 1];
      const top = Math.max(1, ...count);
      return [t0 - (t1 - t0) * 0.03, t1 + (t1 - t0) * 0.03 || t0 + 1, 0, top * 1.05];
    }
    px(x, y) {
      const [x0, x1, y0, y1] = this.view, W = this.canvas.width, H = this.canvas.height, m = this.m;
      return [m.l + (x - x0) / (x1 - x0) * (W - m.l - m.r), H - m.b - (y - y0) / (y1 - y0) * (H - m.t - m.b)];
    }
    at(px, py) {
      const [x0, x1, y0, y1] = this.view, W = this.canvas.width, H = this.canvas.height, m = this.m;
      return [x0 + (px - m.l) / (W - m.l - m.r) * (x1 - x0), y0 + (H - m.b - py) / (H - m.t - m.b) * (y1 - y0)];
    }
    draw() {
      if (!this.view) this.view = this.full();
      const g = this.canvas.getContext("2d"), W = this.canvas.width, H = this.canvas.height, m = this.m;
      g.clearRect(0, 0, W, H);
      g.strokeStyle = "#444"; g.strokeRect(m.l, m.t, W - m.l - m.r, H - m.t - m.b);
      g.fillStyle = "#222"; g.font = "11px sans-serif";
      const [x0, x1, y0, y1] = this.view;
      for (let k = 0; k <= 4; k++) {
        const xv = x0 + (x1 - x0) * k / 4, yv = y0 + (y1 - y0) * k / 4;
        const [px] = this.px(xv, y0), [, py] = this.px(x0, yv);
        g.textAlign = "center";
        g.fillText(fmt(xv), px, H - m.b + 14);
        g.textAlign = "right";
        g.fillText(fmt(yv), m.l - 4, py + 4);
      }
      g.textAlign = "center";
      g.fillText(label(this.xName), m.l + (W - m.l - m.r) / 2, H - 6);
      g.save(); g.translate(12, m.t + (H - m.t - m.b) / 2); g.rotate(-Math.PI / 2);
      g.fillText(this.opts.yLabel || label(this.yName), 0, 0); g.restore();
      g.textAlign = "left";
      g.save(); g.beginPath(); g.rect(m.l, m.t, W - m.l - m.r, H - m.t - m.b); g.clip();
      this.points = this.opts.cumulative ? this.drawLines(g) : this.drawPoints(g);
      g.restore();
      if (this.box) {
        g.strokeStyle = this.box.select ? "#d00" : "#00d";
        g.strokeRect(this.box.a, this.box.b, this.box.c - this.box.a, this.box.d - this.box.b);
      }
      this.drawn = true;
    }
    drawPoints(g) {
      const x = this.xs(), y = this.ys();
      let drawn = 0;
      // While a selection stands, the rest first (faded), the selection on top.
      for (const pass of selecting ? [0, 1] : [1]) {
        for (let i = 0; i < n; i++) {
          if (x[i] === null || y[i] === null) continue;
          if (selecting && mask[i] !== pass) continue;
          const [px, py] = this.px(x[i], y[i]);
          g.fillStyle = selecting && !mask[i] ? "#ddd" : colorOf(i);
          g.fillRect(px - 1.5, py - 1.5, 3, 3);
          drawn++;
        }
      }
      return drawn;
    }
    drawLines(g) {
      const t = this.xs(), c = D.colorings[coloring];
      if (!c) return 0;
      const order = [...Array(n).keys()].filter((i) => t[i] !== null && (!selecting || mask[i]))
        .sort((a, b) => t[a] - t[b]);
      const count = new Array(c.classes.length).fill(0);
      const last = c.classes.map(() => null);
      let drawn = 0;
      g.lineWidth = 1.5;
      for (const i of order) {
        const k = c.of[i];
        if (k === null) continue;
        count[k] += weight(i);
        const p = this.px(t[i], count[k]);
        g.strokeStyle = PAL[k % PAL.length];
        if (last[k]) { g.beginPath(); g.moveTo(last[k][0], last[k][1]); g.lineTo(p[0], p[1]); g.stroke(); }
        last[k] = p; drawn++;
      }
      return drawn;
    }
    // The point nearest (px, py) within 6 px, or -1.
    nearest(px, py) {
      if (this.opts.cumulative) return -1;
      const x = this.xs(), y = this.ys();
      let best = -1, bd = 36;
      for (let i = 0; i < n; i++) {
        if (x[i] === null || y[i] === null) continue;
        const [qx, qy] = this.px(x[i], y[i]);
        const d = (qx - px) * (qx - px) + (qy - py) * (qy - py);
        if (d < bd) { bd = d; best = i; }
      }
      return best;
    }
    listen() {
      const cv = this.canvas;
      const pos = (ev) => { const r = cv.getBoundingClientRect(); return [(ev.clientX - r.left) * cv.width / r.width, (ev.clientY - r.top) * cv.height / r.height]; };
      let down = null;
      cv.addEventListener("mousedown", (ev) => { down = { p: pos(ev), shift: ev.shiftKey, alt: ev.altKey, view: this.view.slice() }; });
      cv.addEventListener("mousemove", (ev) => {
        const p = pos(ev);
        if (down) {
          if (down.alt) {
            const [ax, ay] = this.at(down.p[0], down.p[1]), [bx, by] = this.at(p[0], p[1]);
            const [x0, x1, y0, y1] = this.view;
            this.view = [x0 - (bx - ax), x1 - (bx - ax), y0 - (by - ay), y1 - (by - ay)];
            down.p = p;
          } else {
            this.box = { a: Math.min(down.p[0], p[0]), c: Math.max(down.p[0], p[0]), b: Math.min(down.p[1], p[1]), d: Math.max(down.p[1], p[1]), select: down.shift };
          }
          this.draw();
          return;
        }
        const i = this.nearest(p[0], p[1]);
        const tip = $("ex-tip");
        if (i < 0) { tip.style.display = "none"; return; }
        tip.style.display = "block";
        tip.style.left = (ev.pageX + 12) + "px"; tip.style.top = (ev.pageY + 12) + "px";
        tip.textContent = name(i);
      });
      cv.addEventListener("mouseleave", () => { $("ex-tip").style.display = "none"; });
      window.addEventListener("mouseup", (ev) => {
        if (!down) return;
        const p = pos(ev), b = this.box, d = down;
        down = null; this.box = null;
        if (!b || (b.c - b.a < 4 && b.d - b.b < 4)) {
          if (!d.alt && ev.target === cv) { const i = this.nearest(p[0], p[1]); if (i >= 0) open(i); }
          this.draw();
          return;
        }
        const [ax, ay] = this.at(b.a, b.d), [bx, by] = this.at(b.c, b.b);
        if (b.select) select(this, ax, bx, ay, by);
        else { this.view = [ax, bx, ay, by]; this.draw(); }
      });
      cv.addEventListener("dblclick", () => { this.view = this.full(); this.draw(); });
      cv.addEventListener("keydown", (ev) => {
        const [x0, x1, y0, y1] = this.view, dx = (x1 - x0) / 10, dy = (y1 - y0) / 10;
        const step = { ArrowLeft: [-dx, 0], ArrowRight: [dx, 0], ArrowUp: [0, dy], ArrowDown: [0, -dy] }[ev.key];
        if (!step) return;
        ev.preventDefault();
        this.view = [x0 + step[0], x1 + step[0], y0 + step[1], y1 + step[1]];
        this.draw();
      });
    }
  }

  // The clustering's validity indices against k (its own data, not the points).
  class Validity extends Chart {
    xs() { return D.validity.k; }
    ys() { return D.validity.indices[this.yName]; }
    full() {
      const x = this.xs(), y = this.ys().filter((v) => v !== null);
      if (!y.length) return [0, 1, 0, 1];
      const y0 = Math.min(...y), y1 = Math.max(...y), py = (y1 - y0) * 0.1 || 1;
      return [Math.min(...x) - 0.5, Math.max(...x) + 0.5, y0 - py, y1 + py];
    }
    drawPoints(g) {
      const x = this.xs(), y = this.ys();
      let drawn = 0, last = null;
      g.strokeStyle = "#1f77b4"; g.fillStyle = "#1f77b4"; g.lineWidth = 1.5;
      for (let i = 0; i < x.length; i++) {
        if (y[i] === null) { last = null; continue; }
        const p = this.px(x[i], y[i]);
        if (last) { g.beginPath(); g.moveTo(last[0], last[1]); g.lineTo(p[0], p[1]); g.stroke(); }
        g.fillRect(p[0] - 3, p[1] - 3, 6, 6);
        if (x[i] === D.validity.chosen) {
          g.beginPath(); g.arc(p[0], p[1], 8, 0, 2 * Math.PI); g.stroke();
          g.fillText("k = " + x[i] + " chosen", p[0] + 10, p[1] - 8);
        }
        last = p; drawn++;
      }
      return drawn;
    }
    nearest() { return -1; }
  }

  function fmt(v) {
    const a = Math.abs(v);
    return a !== 0 && (a < 1e-3 || a >= 1e5) ? v.toExponential(1) : +v.toPrecision(3) + "";
  }
  function name(i) {
    const c = classOf(i);
    return D.experiments[D.exp[i]] + " · ch" + D.ch[i] + " · hit " + D.hit[i] +
      (c !== null ? " · " + D.colorings[coloring].name + ": " + c : "");
  }
  // Select the points inside a chart's region (a cumulative chart: its time range).
  function select(chart, x0, x1, y0, y1) {
    if (chart instanceof Validity) { chart.draw(); return; }
    const x = chart.xs(), y = chart.ys();
    let k = 0;
    for (let i = 0; i < n; i++) {
      const inX = x[i] !== null && x[i] >= x0 && x[i] <= x1;
      const inY = chart.opts.cumulative || (y[i] !== null && y[i] >= y0 && y[i] <= y1);
      mask[i] = inX && inY ? 1 : 0; k += mask[i];
    }
    selecting = true;
    $("ex-sel").textContent = k + " points selected";
    for (const c of charts) if (c.opts.cumulative) c.view = null;
    redraw();
  }
  function open(i) {
    const key = keyOf(i), det = $("ex-detail");
    det.innerHTML = "";
    const h = document.createElement("h3");
    h.textContent = name(i);
    det.appendChild(h);
    const dl = document.createElement("p");
    dl.textContent = D.columns.map((c) => c.label + " " + (c.v[i] === null ? "–" : fmt(c.v[i]))).join(" · ");
    det.appendChild(dl);
    const pic = emb.has(key) ? document.querySelector('img[data-key="' + CSS.escape(key) + '"]') : null;
    if (pic) {
      const img = document.createElement("img");
      img.src = pic.dataset.alt || pic.src;
      img.alt = "waveform and CWT of " + name(i);
      img.className = "ex-cwt";
      img.style.maxWidth = "100%";
      det.appendChild(img);
    } else {
      const p = document.createElement("p");
      p.textContent = "Not embedded in this page; to draw its waveform and CWT:";
      const pre = document.createElement("pre");
      pre.className = "ex-cmd";
      pre.textContent = "aepipe cwt " + D.inputs + " --experiment '" + D.experiments[D.exp[i]] +
        "' --channel " + D.ch[i] + " --hit " + D.hit[i] + " --png hit.png";
      det.appendChild(p); det.appendChild(pre);
    }
    det.dataset.key = key;
  }
  function legend() {
    const c = D.colorings[coloring], L = $("ex-legend");
    L.innerHTML = "";
    if (!c) return;
    c.classes.forEach((name, k) => {
      const s = document.createElement("span");
      s.style.cssText = "margin-right:12px;color:" + PAL[k % PAL.length];
      s.textContent = "■ " + name;
      L.appendChild(s);
    });
  }
  function redraw() { for (const c of charts) c.draw(); legend(); }

  const names = D.columns.map((c) => c.name).filter(has);
  const options = (sel, chosen) => {
    for (const nm of names) {
      const o = document.createElement("option");
      o.value = nm; o.textContent = label(nm); o.selected = nm === chosen;
      sel.appendChild(o);
    }
  };
  const pick = (...want) => want.find((w) => names.includes(w)) || names[0];
  const sx = pick("ra_ms_per_v", "peak_amplitude_db"), sy = pick("af_khz", "peak_freq_hz");
  const st = pick("load_n", "peak_amplitude_db");
  options($("ex-x"), sx); options($("ex-y"), sy);
  options($("ex-t"), st);
  D.colorings.forEach((c, k) => {
    const o = document.createElement("option");
    o.value = k; o.textContent = c.name; o.selected = k === coloring;
    $("ex-color").appendChild(o);
  });
  const charts = [];
  const tname = has("time_s") ? "time_s" : names[0];
  const over = new Chart("Over the test", tname, st);
  const scatter = new Chart("Feature scatter", sx, sy);
  charts.push(over, scatter);
  if (D.loc_x && D.loc_x.some((v) => v !== null)) {
    const planar = D.loc_y && D.loc_y.some((v) => v !== null);
    charts.push(new Chart("Event location", "loc_x", planar ? "loc_y" : tname));
  }
  if (D.colorings.length) {
    charts.push(new Chart("Cumulative hits per class", tname, tname,
      { cumulative: true, yLabel: D.w || D.stride > 1 ? "cumulative hits (points × rows each)" : "cumulative hits" }));
  }
  if (D.validity && Object.keys(D.validity.indices).length) {
    const names = Object.keys(D.validity.indices);
    const v = new Validity("Validity against k", "k", names[0]);
    charts.push(v);
    const sel = document.createElement("select");
    sel.id = "ex-v";
    for (const nm of names) {
      const o = document.createElement("option");
      o.value = nm; o.textContent = nm; sel.appendChild(o);
    }
    sel.onchange = (e) => { v.yName = e.target.value; v.view = null; v.draw(); };
    v.fig.querySelector("figcaption").append(" — index ", sel);
  }
  $("ex-x").onchange = (e) => { scatter.xName = e.target.value; scatter.view = null; scatter.draw(); };
  $("ex-y").onchange = (e) => { scatter.yName = e.target.value; scatter.view = null; scatter.draw(); };
  $("ex-t").onchange = (e) => { over.yName = e.target.value; over.view = null; over.draw(); };
  $("ex-color").onchange = (e) => { coloring = +e.target.value; for (const c of charts) if (c.opts.cumulative) c.view = null; redraw(); };
  $("ex-clear").onclick = () => {
    selecting = false; mask.fill(0); $("ex-sel").textContent = "";
    for (const c of charts) if (c.opts.cumulative) c.view = null;
    redraw();
  };
  redraw();
  // For scripted checks (the browser test) and the console.
  window.aepipeExplore = {
    D, charts, open, select, keyOf, embedded: emb,
    // The keys of the points a selection holds (none while nothing is selected).
    selected: () => (selecting ? [...mask.keys()].filter((i) => mask[i]).map(keyOf) : []),
  };
})();
