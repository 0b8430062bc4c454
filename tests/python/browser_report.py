"""Open an aepipe report in headless Chromium through the DevTools protocol and check it.

Usage: python3 browser_report.py REPORT.html

Prints one JSON object: the console errors and exceptions, the requests that left the
file (the report must need no network), each explorable chart's drawn point count, the time
to first contentful paint, what a real mouse click on a point opened, and geometry and
interaction against the run's own tables (where points are drawn, what a drag zooms to,
what a Shift-drag selects and highlights, what each colouring's legend lists). Exit 3 when
Chromium or websocket-client is missing (the Rust test then skips, or fails under
AEPIPE_REQUIRE_ALL=1).
"""

import json
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


def interact(page, run):
    """Geometry and interaction, each against values read here from the run's own tables
    (pyarrow), not from the page: where a hit's point is drawn, what a drag zooms to, which
    hits a Shift-drag selects and whether every chart highlights them, and what each colouring's
    legend lists."""
    try:
        import pyarrow.parquet as pq
    except ImportError as e:
        print(f"missing: {e} (pip install pyarrow)", file=sys.stderr)
        sys.exit(3)
    table = lambda name: pq.read_table(os.path.join(run, name)).to_pylist() if os.path.exists(os.path.join(run, name)) else []  # noqa: E731
    feats = {f"{r['experiment']}|{r['channel']}|{r['hit']}": r for r in table("features/features.parquet")}
    state = lambda i: page.eval(f"""(() => {{  // noqa
      const c = aepipeExplore.charts[{i}]; c.canvas.scrollIntoView({{block: 'center'}});
      const r = c.canvas.getBoundingClientRect();
      return {{view: c.view, W: c.canvas.width, H: c.canvas.height, m: c.m, x: c.xName, y: c.yName,
               rect: {{left: r.left, top: r.top, width: r.width, height: r.height}}}};
    }})()""")
    def pixel(s, x, y):
        x0, x1, y0, y1 = s["view"]
        m = s["m"]
        return (m["l"] + (x - x0) / (x1 - x0) * (s["W"] - m["l"] - m["r"]),
                s["H"] - m["b"] - (y - y0) / (y1 - y0) * (s["H"] - m["t"] - m["b"]))
    def ink(i, px, py):
        # The colours within 2 px of (px, py) on chart i's canvas, as "#rrggbb" (white: none).
        return page.eval(f"""(() => {{
          const g = aepipeExplore.charts[{i}].canvas.getContext('2d');
          const d = g.getImageData({round(px) - 2}, {round(py) - 2}, 5, 5).data, out = new Set();
          for (let k = 0; k < d.length; k += 4) if (d[k + 3] > 0)
            out.add('#' + [d[k], d[k + 1], d[k + 2]].map(v => v.toString(16).padStart(2, '0')).join(''));
          return [...out];
        }})()""")
    out = {}
    # Where points are drawn: the scatter's first hits, their pixels from their own values.
    page.eval("(() => { const c = aepipeExplore.charts[1]; c.view = null; c.draw(); })()")
    s = state(1)
    placed = []
    for key, r in feats.items():
        x, y = r.get(s["x"]), r.get(s["y"])
        if x is None or y is None:
            continue
        px, py = pixel(s, x, y)
        theirs = page.eval(f"""(() => {{ const E = aepipeExplore, c = E.charts[1];
          for (let i = 0; i < E.D.hit.length; i++) if (E.keyOf(i) === {json.dumps(key)})
            return c.px(c.xs()[i], c.ys()[i]);
          return null; }})()""")
        placed.append({"key": key, "expected": [px, py], "chart": theirs,
                       "ink": [c for c in ink(1, px, py) if c != "#ffffff"]})
        if len(placed) == 8:
            break
    out["placed"] = placed
    # Zoom: a drag over the scatter's inner box shows exactly the dragged ranges.
    m = s["m"]
    a, b = drag(page, s["rect"], (s["W"], s["H"]), (m["l"] + 150.0, m["t"] + 40.0),
                (m["l"] + 500.0, m["t"] + 220.0))
    x0, x1, y0, y1 = s["view"]
    at = lambda p: (x0 + (p[0] - m["l"]) / (s["W"] - m["l"] - m["r"]) * (x1 - x0),  # noqa: E731
                    y0 + (s["H"] - m["b"] - p[1]) / (s["H"] - m["t"] - m["b"]) * (y1 - y0))
    (ax, ay_top), (bx, by_low) = at(a), at(b)
    out["zoom"] = {"expected": [ax, bx, by_low, ay_top], "view": state(1)["view"]}
    # A Shift-drag selection on the full scatter: the hits whose values fall in the box.
    page.eval("(() => { const c = aepipeExplore.charts[1]; c.view = null; c.draw(); })()")
    s = state(1)
    sa, sb = drag(page, s["rect"], (s["W"], s["H"]), a, b, shift=True)
    (ax, ay_top), (bx, by_low) = at(sa), at(sb)
    want = sorted(k for k, r in feats.items()
                  if r.get(s["x"]) is not None and r.get(s["y"]) is not None
                  and ax <= r[s["x"]] <= bx and by_low <= r[s["y"]] <= ay_top)
    got = sorted(page.eval("aepipeExplore.selected()"))
    shown = page.eval("document.getElementById('ex-sel').textContent")
    # Every point chart highlights them: a selected hit's pixel carries a class colour, not
    # the faded grey of the rest, in the chart over the test as in the scatter.
    s0 = state(0)
    highlighted = []
    for key in want[:6]:
        r = feats[key]
        if r.get(s0["x"]) is None or r.get(s0["y"]) is None:
            continue
        cs = [c for c in ink(0, *pixel(s0, r[s0["x"]], r[s0["y"]])) if c not in ("#ffffff",)]
        highlighted.append({"key": key, "colours": cs})
    faded = []
    for key, r in feats.items():
        if key in want or r.get(s["x"]) is None or r.get(s["y"]) is None:
            continue
        faded.extend(ink(1, *pixel(s, r[s["x"]], r[s["y"]])))
        if len(faded) > 40:
            break
    out["selection"] = {"expected": want, "selected": got, "said": shown,
                        "highlighted": highlighted, "grey_seen": "#dddddd" in faded}
    page.eval("document.getElementById('ex-clear').click()")
    # Colour switching: each colouring's legend lists the run's own classes of it.
    cls = table("som/classification.parquet")
    clu = table("cluster/clusters.parquet")
    truth = {
        "SOM class": {r["som_label"] for r in cls if r["som_label"] is not None},
        "cluster": {str(r["cluster"]) for r in clu},
        "zone": {r["zone"] for r in feats.values() if r.get("zone") is not None},
        "ch. 4.7 label": {r["criteria_label"] for r in feats.values() if r.get("criteria_label") is not None},
    }
    legends = {}
    n = page.eval("document.getElementById('ex-color').options.length")
    for k in range(n):
        name, text = page.eval(f"""(() => {{ const s = document.getElementById('ex-color');
          s.value = '{k}'; s.dispatchEvent(new Event('change'));
          return [s.options[{k}].textContent, document.getElementById('ex-legend').textContent]; }})()""")
        legends[name] = {"legend": sorted(t.strip() for t in text.split("■") if t.strip()),
                         "expected": sorted(truth[name]) if name in truth else None}
    out["legends"] = legends
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
