"""Open an aepipe report in headless Chromium through the DevTools protocol and check it.

Usage: python3 browser_report.py REPORT.html

Prints one JSON object: the console errors and exceptions, the requests that left the
file (the report must need no network), each explorable chart's drawn point count, the time
to first contentful paint, and what a real mouse click on a point opened. Exit 3 when
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
            "bytes": os.path.getsize(report),
        }))
    finally:
        proc.kill()
        proc.wait()
        shutil.rmtree(profile, ignore_errors=True)


if __name__ == "__main__":
    main()
