"""Open an aepipe report in headless Chromium through the DevTools protocol and check it.

Usage: python3 browser_report.py REPORT.html

Prints one JSON object: the console errors and exceptions, the requests that left the
file (the report must need no network), each explorable chart's drawn point count, the time
to first contentful paint, what a real mouse click on a point opened, and geometry and
interaction against the run's own tables (where points are drawn and how the axes are
labelled, against axis ranges derived here from the values; the same with the page's ranges
planted 10 % wider; what a drag zooms to, what a Shift-drag selects and highlights, what
each colouring's legend lists, which tables are missing). Exit 3 when
Chromium or websocket-client is missing (the Rust test then skips, or fails under
AEPIPE_REQUIRE_ALL=1).
"""

import json
import math
import os
import shutil
import subprocess
import sys
import tempfile
import time
import urllib.request

try:
    import websocket  # websocket-client
except ImportError as e:
    print(f"missing: {e} (pip install websocket-client)", file=sys.stderr)
    sys.exit(3)

CHROME = next(
    (shutil.which(c) for c in ("chromium", "chromium-browser", "google-chrome") if shutil.which(c)),
    None,
)
if CHROME is None:
    print("missing: chromium (apt-get install chromium)", file=sys.stderr)
    sys.exit(3)


class Page:
    """One page target, driven over its DevTools websocket."""

    def __init__(self, ws_url):
        self.ws = websocket.create_connection(ws_url, timeout=60, suppress_origin=True)
        self.n = 0
        self.events = []

    def call(self, method, **params):
        self.n += 1
        me = self.n
        self.ws.send(json.dumps({"id": me, "method": method, "params": params}))
        while True:
            m = json.loads(self.ws.recv())
            if m.get("id") == me:
                if "error" in m:
                    raise RuntimeError(f"{method}: {m['error']}")
                return m.get("result", {})
            self.events.append(m)

    def wait_for(self, method, seconds=60):
        t0 = time.time()
        while time.time() - t0 < seconds:
            for m in self.events:
                if m.get("method") == method:
                    return m
            self.events.append(json.loads(self.ws.recv()))
        raise TimeoutError(method)

    def eval(self, js):
        r = self.call("Runtime.evaluate", expression=js, returnByValue=True, awaitPromise=True)
        if "exceptionDetails" in r:
            raise RuntimeError(f"{js[:80]}: {r['exceptionDetails']}")
        return r["result"].get("value")

    def click(self, x, y):
        for kind in ("mouseMoved", "mousePressed", "mouseReleased"):
            self.call("Input.dispatchMouseEvent", type=kind, x=x, y=y, button="left", clickCount=1)


def drag(page, rect, canvas, a, b, shift=False):
    """A real mouse drag on a chart from about canvas point a to b (Shift held: a
    selection), at whole CSS pixels; the canvas points the page receives, exactly."""
    sx, sy = rect["width"] / canvas[0], rect["height"] / canvas[1]
    to = lambda p: (round(rect["left"] + p[0] * sx), round(rect["top"] + p[1] * sy))  # noqa: E731
    back = lambda c: ((c[0] - rect["left"]) / sx, (c[1] - rect["top"]) / sy)  # noqa: E731
    mods = 8 if shift else 0
    (x0, y0), (x1, y1) = to(a), to(b)
    page.call("Input.dispatchMouseEvent", type="mouseMoved", x=x0, y=y0, modifiers=mods)
    page.call("Input.dispatchMouseEvent", type="mousePressed", x=x0, y=y0, button="left",
              clickCount=1, modifiers=mods)
    for k in range(1, 6):
        page.call("Input.dispatchMouseEvent", type="mouseMoved", x=round(x0 + (x1 - x0) * k / 5),
                  y=round(y0 + (y1 - y0) * k / 5), button="left", buttons=1, modifiers=mods)
    page.call("Input.dispatchMouseEvent", type="mouseReleased", x=x1, y=y1, button="left",
              clickCount=1, modifiers=mods)
    return back((x0, y0)), back((x1, y1))


# The tables the checks read, by the part of the run they come from.
FEATURES, CLASSES, CLUSTERS = ("features/features.parquet", "som/classification.parquet",
                               "cluster/clusters.parquet")


def read_tables(run, absent=()):
    """The rows of each table the checks need (pyarrow, not the page), and the ones missing:
    a missing table is reported, never read as an empty one. `absent` names tables to treat
    as missing (the planted absence)."""
    try:
        import pyarrow.parquet as pq
    except ImportError as e:
        print(f"missing: {e} (pip install pyarrow)", file=sys.stderr)
        sys.exit(3)
    rows, missing = {}, []
    for name in (FEATURES, CLASSES, CLUSTERS):
        path = os.path.join(run, name)
        if name in absent or not os.path.exists(path):
            missing.append(name)
        else:
            rows[name] = pq.read_table(path).to_pylist()
    return rows, missing


def truth(rows):
    """Each colouring's classes as the run's tables hold them (None: its table is missing)."""
    feats, cls, clu = rows.get(FEATURES), rows.get(CLASSES), rows.get(CLUSTERS)
    of = lambda t, f: None if t is None else {f(r) for r in t} - {None}  # noqa: E731
    return {
        "SOM class": of(cls, lambda r: r["som_label"]),
        "cluster": of(clu, lambda r: None if r["cluster"] is None else str(r["cluster"])),
        "zone": of(feats, lambda r: r.get("zone")),
        "ch. 4.7 label": of(feats, lambda r: r.get("criteria_label")),
    }


def plotted(r, name):
    """A row's value on an axis as the page's documented rule plots it: energy as its
    logarithm (none at or below 0), a missing or non-finite value not at all."""
    v = r.get(name)
    if v is None or not math.isfinite(v):
        return None
    if name == "energy_eu":
        return math.log10(v) if v > 0 else None
    return v


def full_view(feats, xn, yn):
    """A point chart's full axis ranges, derived here from the table's values: the data's
    extent padded by 3 % of its width in x and 5 % of its height in y (1 where the extent is
    0), the rule explore.js's Chart.full states."""
    pts = [(plotted(r, xn), plotted(r, yn)) for r in feats]
    pts = [(x, y) for x, y in pts if x is not None and y is not None]
    xs, ys = [p[0] for p in pts], [p[1] for p in pts]
    x0, x1, y0, y1 = min(xs), max(xs), min(ys), max(ys)
    px, py = (x1 - x0) * 0.03 or 1, (y1 - y0) * 0.05 or 1
    return [x0 - px, x1 + px, y0 - py, y1 + py]


def frame(counts, size):
    """The two frame lines among pixel columns (or rows) by their count of the frame's
    colour: the centre of the first and of the last run of lines longer than 40 % of the
    canvas (a 1-px stroke on a whole coordinate covers the two pixels either side)."""
    lines = [k for k, c in enumerate(counts) if c > 0.4 * size]
    if not lines:
        return None
    runs, start = [], lines[0]
    for a, b in zip(lines, lines[1:] + [None]):
        if b != a + 1:
            runs.append((start + a + 1) / 2)
            start = b
    return runs[0], runs[-1]


def interact(page, run):
    """Geometry and interaction, each against values read here from the run's own tables
    (pyarrow), not from the page: where a hit's point is drawn and what the axes are
    labelled (from axis ranges derived here from the values, and the frame the page drew),
    the same after a planted 10 % widening of the page's axis ranges, what a drag zooms to,
    which hits a Shift-drag selects and whether every chart highlights them, what each
    colouring's legend lists, and which tables were missing."""
    rows, missing = read_tables(run)
    feats = {f"{r['experiment']}|{r['channel']}|{r['hit']}": r for r in rows.get(FEATURES, [])}
    out = {"missing": missing}
    def state(i):
        # What chart i draws after a redraw: its canvas, axes' names, the frame's lines from
        # its pixels, the tick labels it wrote; with the axis ranges derived from the table.
        s = page.eval(f"""(() => {{
          const c = aepipeExplore.charts[{i}]; c.canvas.scrollIntoView({{block: 'center'}});
          const g = c.canvas.getContext('2d'), texts = [];
          g.fillText = function (t, x, y) {{
            texts.push([String(t), this.textAlign]);
            return CanvasRenderingContext2D.prototype.fillText.apply(this, arguments); }};
          c.draw(); delete g.fillText;
          const W = c.canvas.width, H = c.canvas.height, d = g.getImageData(0, 0, W, H).data;
          const cols = new Array(W).fill(0), rows = new Array(H).fill(0);
          for (let y = 0; y < H; y++) for (let x = 0; x < W; x++) {{
            const k = 4 * (y * W + x);
            if (d[k + 3] > 0 && [0, 1, 2].every((j) => Math.abs(d[k + j] - 0x44) <= 6)) {{
              cols[x]++; rows[y]++; }}
          }}
          const r = c.canvas.getBoundingClientRect();
          return {{W, H, x: c.xName, y: c.yName, cols, rows, texts,
                   rect: {{left: r.left, top: r.top, width: r.width, height: r.height}}}};
        }})()""")
        s["box"] = frame(s.pop("cols"), s["H"]), frame(s.pop("rows"), s["W"])
        s["full"] = full_view(feats.values(), s["x"], s["y"]) if feats else None
        ticks = lambda align: [t for t, a in s["texts"] if a == align and number(t) is not None]  # noqa: E731
        s["ticks"] = {"x": ticks("center"), "y": ticks("right")}
        return s
    def number(t):
        try:
            return float(t)
        except ValueError:
            return None
    def pixel(s, x, y):
        (l, r), (t, b) = s["box"]
        x0, x1, y0, y1 = s["full"]
        return (l + (x - x0) / (x1 - x0) * (r - l), b - (y - y0) / (y1 - y0) * (b - t))
    def at(s, p):
        (l, r), (t, b) = s["box"]
        x0, x1, y0, y1 = s["full"]
        return (x0 + (p[0] - l) / (r - l) * (x1 - x0), y0 + (b - p[1]) / (b - t) * (y1 - y0))
    def ink(i, px, py):
        # The colours within 2 px of (px, py) on chart i's canvas, as "#rrggbb" (white: none).
        return page.eval(f"""(() => {{
          const g = aepipeExplore.charts[{i}].canvas.getContext('2d');
          const d = g.getImageData({round(px) - 2}, {round(py) - 2}, 5, 5).data, out = new Set();
          for (let k = 0; k < d.length; k += 4) if (d[k + 3] > 0)
            out.add('#' + [d[k], d[k + 1], d[k + 2]].map(v => v.toString(16).padStart(2, '0')).join(''));
          return [...out];
        }})()""")
    def geometry():
        # Where the scatter's points are drawn, against where their values put them: the
        # hits at the extremes of each axis (any error in a range moves them), then the first.
        page.eval("(() => { const c = aepipeExplore.charts[1]; c.view = null; c.draw(); })()")
        s = state(1)
        on = [(k, plotted(r, s["x"]), plotted(r, s["y"])) for k, r in feats.items()]
        on = [p for p in on if p[1] is not None and p[2] is not None]
        chosen = []
        for p in [min(on, key=lambda p: p[1]), max(on, key=lambda p: p[1]),
                  min(on, key=lambda p: p[2]), max(on, key=lambda p: p[2])] + on if on else []:
            if p not in chosen and len(chosen) < 8:
                chosen.append(p)
        placed = []
        for key, x, y in chosen:
            px, py = pixel(s, x, y)
            theirs = page.eval(f"""(() => {{ const E = aepipeExplore, c = E.charts[1];
              for (let i = 0; i < E.D.hit.length; i++) if (E.keyOf(i) === {json.dumps(key)})
                return c.px(c.xs()[i], c.ys()[i]);
              return null; }})()""")
            placed.append({"key": key, "expected": [px, py], "chart": theirs,
                           "ink": [c for c in ink(1, px, py) if c != "#ffffff"]})
        return s, {"placed": placed, "box": s["box"], "full": s["full"], "ticks": s["ticks"]}
    if not feats:
        return out
    s, out["geometry"] = geometry()
    # The plant: the page's axis ranges widened by 10 % (the full view's prototype method
    # replaced for the scatter, then restored); the same measurement must disagree.
    page.eval("""(() => { const P = Object.getPrototypeOf(aepipeExplore.charts[1]);
      P.unplanted = P.full;
      P.full = function () { const [a, b, c, d] = this.unplanted(), w = (b - a) * 0.05,
        h = (d - c) * 0.05; return [a - w, b + w, c - h, d + h]; }; })()""")
    _, out["planted_wide_axes"] = geometry()
    page.eval("""(() => { const P = Object.getPrototypeOf(aepipeExplore.charts[1]);
      P.full = P.unplanted; delete P.unplanted; })()""")
    s, _ = geometry()
    # Zoom: a drag over the scatter's inner box shows exactly the dragged ranges.
    (l, _r), (t, _b) = s["box"]
    a, b = drag(page, s["rect"], (s["W"], s["H"]), (l + 150.0, t + 40.0), (l + 500.0, t + 220.0))
    (ax, ay_top), (bx, by_low) = at(s, a), at(s, b)
    out["zoom"] = {"expected": [ax, bx, by_low, ay_top],
                   "view": page.eval("aepipeExplore.charts[1].view")}
    # A Shift-drag selection on the full scatter: the hits whose values fall in the box.
    page.eval("(() => { const c = aepipeExplore.charts[1]; c.view = null; c.draw(); })()")
    s = state(1)
    sa, sb = drag(page, s["rect"], (s["W"], s["H"]), a, b, shift=True)
    (ax, ay_top), (bx, by_low) = at(s, sa), at(s, sb)
    inside = lambda r, s: None not in (plotted(r, s["x"]), plotted(r, s["y"]))  # noqa: E731
    want = sorted(k for k, r in feats.items() if inside(r, s)
                  and ax <= plotted(r, s["x"]) <= bx and by_low <= plotted(r, s["y"]) <= ay_top)
    got = sorted(page.eval("aepipeExplore.selected()"))
    shown = page.eval("document.getElementById('ex-sel').textContent")
    # Every point chart highlights them: a selected hit's pixel carries a class colour, not
    # the faded grey of the rest, in the chart over the test as in the scatter.
    s0 = state(0)
    highlighted = []
    for key in want[:6]:
        r = feats[key]
        if not inside(r, s0):
            continue
        cs = [c for c in ink(0, *pixel(s0, plotted(r, s0["x"]), plotted(r, s0["y"])))
              if c != "#ffffff"]
        highlighted.append({"key": key, "colours": cs})
    faded = []
    for key, r in feats.items():
        if key in want or not inside(r, s):
            continue
        faded.extend(ink(1, *pixel(s, plotted(r, s["x"]), plotted(r, s["y"]))))
        if len(faded) > 40:
            break
    out["selection"] = {"expected": want, "selected": got, "said": shown,
                        "highlighted": highlighted, "grey_seen": "#dddddd" in faded}
    page.eval("document.getElementById('ex-clear').click()")
    # Colour switching: what each colouring's legend lists, against the run's own classes
    # of it; and the same legends against the tables with the SOM's classification planted
    # absent (its colouring then has nothing to be checked against).
    shown = {}
    n = page.eval("document.getElementById('ex-color').options.length")
    for k in range(n):
        name, text = page.eval(f"""(() => {{ const s = document.getElementById('ex-color');
          s.value = '{k}'; s.dispatchEvent(new Event('change'));
          return [s.options[{k}].textContent, document.getElementById('ex-legend').textContent]; }})()""")
        shown[name] = sorted(t.strip() for t in text.split("■") if t.strip())
    def legends(rows):
        known = truth(rows)
        return {name: {"legend": legend,
                       "expected": None if known.get(name) is None else sorted(known[name])}
                for name, legend in shown.items()}
    out["legends"] = legends(rows)
    planted_rows, planted_missing = read_tables(run, absent=(CLASSES,))
    out["planted_absent"] = {"missing": planted_missing, "legends": legends(planted_rows)}
    return out


def main():
    report = os.path.abspath(sys.argv[1])
    profile = tempfile.mkdtemp()
    proc = subprocess.Popen(
        [CHROME, "--headless=new", "--no-sandbox", "--disable-gpu", "--no-first-run",
         "--remote-debugging-port=0", f"--user-data-dir={profile}", "--window-size=1400,1800",
         "about:blank"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    try:
        port = None
        t0 = time.time()
        while port is None and time.time() - t0 < 60:
            line = proc.stderr.readline()
            if "DevTools listening on ws://" in line:
                port = int(line.split("ws://")[1].split("/")[0].split(":")[1])
        if port is None:
            raise RuntimeError("Chromium gave no DevTools port")
        targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list"))
        page = Page(next(t for t in targets if t["type"] == "page")["webSocketDebuggerUrl"])
        for domain in ("Runtime", "Log", "Page", "Network", "Performance"):
            page.call(f"{domain}.enable")
        start = time.time()
        page.call("Page.navigate", url="file://" + report)
        page.wait_for("Page.loadEventFired", 120)
        load_s = time.time() - start
        paint = page.eval("""new Promise((done) => {
            const now = performance.getEntriesByName('first-contentful-paint')[0];
            if (now) return done(now.startTime);
            new PerformanceObserver((l) => {
              const e = l.getEntriesByName('first-contentful-paint')[0];
              if (e) done(e.startTime);
            }).observe({type: 'paint', buffered: true});
            setTimeout(() => done(null), 5000);
          })""")
        charts = page.eval(
            "JSON.stringify(window.aepipeExplore ? aepipeExplore.charts.map("
            "c => ({title: c.title, drawn: c.drawn, points: c.points})) : null)")
        # A real click on a point of the feature scatter whose picture the page embeds, and
        # on one it does not: the point is the one the chart itself finds nearest there.
        clicks = []
        for embedded in (True, False):
            where = page.eval(f"""(() => {{
              const E = aepipeExplore, c = E.charts[1], xs = c.xs(), ys = c.ys();
              c.canvas.scrollIntoView({{block: 'center'}});
              const r = c.canvas.getBoundingClientRect();
              for (let i = 0; i < E.D.hit.length; i++) {{
                if (xs[i] === null || ys[i] === null) continue;
                if (E.embedded.has(E.keyOf(i)) !== {str(embedded).lower()}) continue;
                const [px, py] = c.px(xs[i], ys[i]);
                if (px < c.m.l || py < c.m.t || px > c.canvas.width - c.m.r) continue;
                if (c.nearest(px, py) !== i) continue;
                return {{i, key: E.keyOf(i), x: r.left + px * r.width / c.canvas.width,
                         y: r.top + py * r.height / c.canvas.height}};
              }}
              return null;
            }})()""")
            if where is None:
                clicks.append({"embedded": embedded, "found": False})
                continue
            page.click(where["x"], where["y"])
            opened = page.eval("""(async () => {
              const d = document.getElementById('ex-detail'), img = d.querySelector('img.ex-cwt');
              if (img) { await img.decode().catch(() => null); }
              const cmd = d.querySelector('pre.ex-cmd');
              return {key: d.dataset.key || null, title: (d.querySelector('h3') || {}).textContent || '',
                      image_width: img ? img.naturalWidth : 0, command: cmd ? cmd.textContent : null};
            })()""")
            clicks.append({"embedded": embedded, "found": True, "expected": where["key"], **opened})
        interaction = interact(page, os.path.dirname(report))
        errors = []
        requests = []
        for m in page.events:
            meth, p = m.get("method"), m.get("params", {})
            if meth == "Runtime.exceptionThrown":
                errors.append(p["exceptionDetails"].get("text", "") + " " + str(
                    p["exceptionDetails"].get("exception", {}).get("description", "")))
            elif meth == "Runtime.consoleAPICalled" and p.get("type") in ("error", "assert"):
                errors.append(" ".join(str(a.get("value", a.get("description", ""))) for a in p["args"]))
            elif meth == "Log.entryAdded" and p["entry"]["level"] == "error":
                errors.append(p["entry"].get("text", ""))
            elif meth == "Network.requestWillBeSent":
                url = p["request"]["url"]
                if not url.startswith(("data:", "file:", "about:")):
                    requests.append(url)
        print(json.dumps({
            "errors": errors, "requests": requests, "charts": json.loads(charts or "null"),
            "clicks": clicks, "first_paint_ms": paint, "load_s": load_s,
            "interaction": interaction,
            "bytes": os.path.getsize(report),
        }))
    finally:
        proc.kill()
        proc.wait()
        shutil.rmtree(profile, ignore_errors=True)


if __name__ == "__main__":
    main()
