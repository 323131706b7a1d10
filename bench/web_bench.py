#!/usr/bin/env python3
"""The web page's speed and size (docs/performance.md, "The web page"), measured in headless Chromium.

  python3 bench/web_bench.py [--site build-web/site] [--binary build/flatland] [--runs 3]

Prints, each as the median of --runs runs (the page and the native program interleaved):
  - photons per second of the testing hook's solve (report=1, one thread) against
    `flatland solve --threads 1` on the same scene and options, and their ratio;
  - the time from opening the page to the first photons on screen, and the frames and photons per
    second of the live viewer at 1280x720 while it shoots (Chromium's software WebGL, SwiftShader);
  - the site's size, as served and compressed with gzip -9.
Chromium is driven through its DevTools protocol (a minimal WebSocket client below, standard
library only), so the page's clocks run in real time.
"""
import argparse
import base64
import functools
import gzip
import http.server
import json
import os
import socket
import statistics
import struct
import subprocess
import sys
import tempfile
import threading
import time
import urllib.request


class Quiet(http.server.SimpleHTTPRequestHandler):
    def log_message(self, *args):
        pass


class DevTools:
    """One page target of Chromium's DevTools protocol over a WebSocket."""

    def __init__(self, ws_url):
        host_port, path = ws_url[len("ws://"):].split("/", 1)
        host, port = host_port.split(":")
        self.sock = socket.create_connection((host, int(port)))
        key = base64.b64encode(os.urandom(16)).decode()
        self.sock.sendall((f"GET /{path} HTTP/1.1\r\nHost: {host_port}\r\nUpgrade: websocket\r\n"
                           f"Connection: Upgrade\r\nSec-WebSocket-Key: {key}\r\nSec-WebSocket-Version: 13\r\n\r\n").encode())
        response = b""
        while b"\r\n\r\n" not in response:
            response += self.sock.recv(4096)
        assert b" 101 " in response.split(b"\r\n")[0], response
        self.buffer = response.split(b"\r\n\r\n", 1)[1]
        self.next_id = 0

    def _read(self, n):
        while len(self.buffer) < n:
            chunk = self.sock.recv(1 << 16)
            if not chunk:
                raise ConnectionError("DevTools closed the connection")
            self.buffer += chunk
        data, self.buffer = self.buffer[:n], self.buffer[n:]
        return data

    def _send(self, text):
        payload = text.encode()
        header = bytes([0x81])
        if len(payload) < 126:
            header += bytes([0x80 | len(payload)])
        elif len(payload) < 1 << 16:
            header += bytes([0x80 | 126]) + struct.pack(">H", len(payload))
        else:
            header += bytes([0x80 | 127]) + struct.pack(">Q", len(payload))
        mask = os.urandom(4)
        self.sock.sendall(header + mask + bytes(b ^ mask[i % 4] for i, b in enumerate(payload)))

    def _message(self):
        text = b""
        while True:
            first, second = self._read(2)
            length = second & 0x7F
            if length == 126:
                length = struct.unpack(">H", self._read(2))[0]
            elif length == 127:
                length = struct.unpack(">Q", self._read(8))[0]
            text += self._read(length)
            if first & 0x80:
                return json.loads(text)

    def call(self, method, **params):
        self.next_id += 1
        self._send(json.dumps({"id": self.next_id, "method": method, "params": params}))
        while True:
            message = self._message()
            if message.get("id") == self.next_id:
                if "error" in message:
                    raise RuntimeError(message["error"])
                return message["result"]

    def evaluate(self, expression):
        result = self.call("Runtime.evaluate", expression=expression, awaitPromise=True, returnByValue=True)
        if "exceptionDetails" in result:
            raise RuntimeError(result["exceptionDetails"])
        return result["result"].get("value")


def start_chromium(profile, width=1280, height=720):
    process = subprocess.Popen(
        ["chromium", "--headless", "--no-sandbox", "--no-first-run", f"--user-data-dir={profile}",
         "--enable-unsafe-swiftshader", "--use-angle=swiftshader", f"--window-size={width},{height}",
         "--remote-debugging-port=0", "about:blank"], stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    port_file = os.path.join(profile, "DevToolsActivePort")
    for _ in range(200):
        if os.path.exists(port_file) and open(port_file).read().strip():
            break
        time.sleep(0.05)
    port = int(open(port_file).read().split()[0])
    targets = json.load(urllib.request.urlopen(f"http://127.0.0.1:{port}/json/list"))
    page = next(t for t in targets if t["type"] == "page")
    return process, DevTools(page["webSocketDebuggerUrl"])


def wait_for(tools, condition, timeout=120):
    """Polls the JavaScript `condition` every 10 ms (across the navigation that may be under way)
    until it holds; returns the page's performance.now() in seconds then."""
    end = time.monotonic() + timeout
    while time.monotonic() < end:
        try:
            now = tools.evaluate(f"(() => {{ try {{ return ({condition}) ? performance.now() : null; }} "
                                 f"catch (e) {{ return null; }} }})()")
        except RuntimeError:
            now = None  # the old document went away
        if now is not None:
            return now / 1000.0
        time.sleep(0.01)
    raise TimeoutError(condition)


def page_solve(tools, url, query):
    tools.call("Page.navigate", url=f"{url}?report=1&{query}")
    wait_for(tools, "document.getElementById('flatland-report').textContent.length > 0")
    document = json.loads(tools.evaluate("document.getElementById('flatland-report').textContent"))
    return document["stats"]["photons"], document["stats"]["seconds"]


def native_solve(binary, scene, query):
    with tempfile.TemporaryDirectory() as folder:
        out = os.path.join(folder, "out.json")
        options = [f"--{pair}" for pair in query.split("&")]
        subprocess.run([binary, "solve", scene, *options, "--threads", "1", "--quiet", "--out", out], check=True)
        document = json.load(open(out))
    return document["stats"]["photons"], document["stats"]["seconds"]


def live_viewer(tools, url):
    """Seconds from navigation to the first photons; then frames/s and photons/s over 5 s."""
    # A budget the 5 s cannot spend, so the rate is the shooting rate.
    tools.call("Page.navigate", url=f"{url}?scene=default&photons=1e9&tolerance=1e-12")
    first = wait_for(tools, "document.body.dataset.ready === '1' && Module._flatland_photons() > 0")
    measured = tools.evaluate("""new Promise((resolve) => {
        let frames = 0;
        const start = performance.now();
        const photons = Module._flatland_photons();
        const tick = () => {
          ++frames;
          if (performance.now() - start < 5000) requestAnimationFrame(tick);
          else resolve([frames, (performance.now() - start) / 1000, Module._flatland_photons() - photons]);
        };
        requestAnimationFrame(tick);
      })""")
    frames, seconds, photons = measured
    return first, frames / seconds, photons / seconds


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--site", default="build-web/site")
    parser.add_argument("--binary", default="build/flatland")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--scene", default="penumbra")
    parser.add_argument("--query", default="photons=4e6&tolerance=1e-9")
    args = parser.parse_args()
    site = os.path.abspath(args.site)
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), functools.partial(Quiet, directory=site))
    threading.Thread(target=server.serve_forever, daemon=True).start()
    url = f"http://127.0.0.1:{server.server_address[1]}/index.html"
    scene = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "scenes2d", args.scene + ".json")

    web_rates, native_rates, firsts, fps, live_rates = [], [], [], [], []
    for run in range(args.runs):
        with tempfile.TemporaryDirectory(ignore_cleanup_errors=True) as profile:
            process, tools = start_chromium(profile)
            try:
                photons, seconds = page_solve(tools, url, f"scene={args.scene}&{args.query}")
                web_rates.append(photons / seconds)
                photons, seconds = native_solve(args.binary, scene, args.query)
                native_rates.append(photons / seconds)
                first, frames, rate = live_viewer(tools, url)
                firsts.append(first)
                fps.append(frames)
                live_rates.append(rate)
            finally:
                process.terminate()
                process.wait()
        print(f"run {run + 1}: page {web_rates[-1]:.3g} photons/s, native {native_rates[-1]:.3g} photons/s, "
              f"first photons {firsts[-1]:.2f} s, {fps[-1]:.1f} frames/s, live {live_rates[-1]:.3g} photons/s",
              file=sys.stderr)
    median = statistics.median
    print(f"solve ({args.scene}, {args.query}, one thread): page {median(web_rates):.3g} photons/s, native "
          f"{median(native_rates):.3g} photons/s, ratio {median(w / n for w, n in zip(web_rates, native_rates)):.2f}")
    print(f"viewer (default scene, 1280x720): first photons after {median(firsts):.2f} s; "
          f"{median(fps):.1f} frames/s and {median(live_rates):.3g} photons/s while shooting")
    files = sorted(f for f in os.listdir(site) if not f.startswith("."))
    raw = sum(os.path.getsize(os.path.join(site, f)) for f in files)
    packed = sum(len(gzip.compress(open(os.path.join(site, f), "rb").read(), 9)) for f in files)
    print(f"site: {len(files)} files, {raw / 1e6:.2f} MB as served, {packed / 1e6:.2f} MB with gzip -9 "
          f"({', '.join(files)})")
    server.shutdown()


if __name__ == "__main__":
    main()
