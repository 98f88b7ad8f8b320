#!/usr/bin/env python3
"""Opens a ddhgs report in headless Chromium over the DevTools protocol (pipe
transport, no extra packages) with software WebGL (SwiftShader), and checks
with real input events and from the page:

  - the 3D view draws the model (pixels differ from its background), a band
    chosen with its wavelength slider recolours it, and a click on the model
    plots the spectrum of the Gaussians under the cursor; halfway between two
    bands the slider shows their interpolation (an uncaptured wavelength);
    NDVI recolours it;
  - in the spectral viewer, the slider changes the band image and a click on
    a pixel plots its spectra;
  - the console stays free of errors.

Saves a screenshot of the page and one of the 3D view (SCREENSHOT_PNG with
"_3d" before the extension). Prints one JSON object; exit status 0 when every
check passed.

usage: report_browser_check.py CHROMIUM INDEX_HTML SCREENSHOT_PNG PROFILE_DIR [--no-viewer]

--no-viewer: a report whose scene has no whole-spectrum views (band per view):
the 3D view is checked, and the spectral viewer must say why it is empty.
"""
import base64
import json
import os
import pathlib
import subprocess
import sys
import time

FLAGS = [
    "--headless",
    "--no-sandbox",
    # WebGL without a GPU: ANGLE on SwiftShader, Chromium's CPU renderer.
    "--use-angle=swiftshader",
    "--enable-unsafe-swiftshader",
    "--ignore-gpu-blocklist",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
    "--disable-quic",
    "--remote-debugging-pipe",
    "--window-size=1280,2000",
]
TIMEOUT_S = 60


class DevTools:
    """DevTools protocol over --remote-debugging-pipe: Chromium reads
    NUL-terminated JSON commands on fd 3 and writes replies on fd 4."""

    def __init__(self, chromium, profile):
        to_chrome_r, self.to_chrome = os.pipe()
        self.from_chrome, from_chrome_w = os.pipe()

        def child_fds():
            # Via fresh copies, in case the pipes themselves sit on fds 3 or 4;
            # dup2 leaves the targets inheritable, everything else closes at exec.
            read_end, write_end = os.dup(to_chrome_r), os.dup(from_chrome_w)
            os.dup2(read_end, 3)
            os.dup2(write_end, 4)

        self.proc = subprocess.Popen(
            [chromium] + FLAGS + ["--user-data-dir=" + profile, "about:blank"],
            close_fds=False,
            preexec_fn=child_fds,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        os.close(to_chrome_r)
        os.close(from_chrome_w)
        self.buffer = b""
        self.next_id = 0
        self.events = []
        self.session = None

    def _read_message(self):
        while b"\0" not in self.buffer:
            chunk = os.read(self.from_chrome, 1 << 20)
            if not chunk:
                raise RuntimeError("chromium closed the DevTools pipe")
            self.buffer += chunk
        message, self.buffer = self.buffer.split(b"\0", 1)
        return json.loads(message)

    def send(self, method, params=None, browser=False):
        self.next_id += 1
        command = {"id": self.next_id, "method": method, "params": params or {}}
        if self.session and not browser:
            command["sessionId"] = self.session
        os.write(self.to_chrome, json.dumps(command).encode() + b"\0")
        deadline = time.time() + TIMEOUT_S
        while time.time() < deadline:
            message = self._read_message()
            if message.get("id") == self.next_id:
                if "error" in message:
                    raise RuntimeError(method + ": " + json.dumps(message["error"]))
                return message.get("result", {})
            self.events.append(message)
        raise RuntimeError(method + ": no reply")

    def evaluate(self, expression):
        result = self.send(
            "Runtime.evaluate",
            {"expression": expression, "returnByValue": True, "awaitPromise": True},
        )
        if "exceptionDetails" in result:
            raise RuntimeError("page threw: " + json.dumps(result["exceptionDetails"]))
        return result["result"].get("value")

    def wait_for(self, expression, what):
        deadline = time.time() + TIMEOUT_S
        while time.time() < deadline:
            if self.evaluate(expression):
                return
            time.sleep(0.1)
        # The page's own errors usually say why.
        errors = console_errors(self.events)
        raise RuntimeError("timed out waiting for " + what +
                           ("; console: " + json.dumps(errors) if errors else ""))

    def click(self, x, y):
        for kind in ("mousePressed", "mouseReleased"):
            self.send(
                "Input.dispatchMouseEvent",
                {"type": kind, "x": x, "y": y, "button": "left", "clickCount": 1},
            )

    def close(self):
        try:
            self.send("Browser.close", browser=True)
        except RuntimeError:
            pass
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()


def console_errors(events):
    errors = []
    for e in events:
        method, params = e.get("method"), e.get("params", {})
        if method == "Runtime.consoleAPICalled" and params.get("type") in ("error", "assert"):
            errors.append(" ".join(str(a.get("value", a.get("description"))) for a in params["args"]))
        elif method == "Runtime.exceptionThrown":
            errors.append(json.dumps(params["exceptionDetails"])[:500])
        elif method == "Log.entryAdded" and params["entry"]["level"] == "error":
            errors.append(params["entry"].get("text", "") + " " + params["entry"].get("url", ""))
    return errors


# The 3D view's canvas against its background colour: the fraction of pixels
# that differ, the most different pixel (canvas pixels), and the pixels as a
# data URL. The canvas keeps its drawing buffer, so it can be read any time.
SPLAT_PIXELS = """(() => { const c = document.getElementById('splat-canvas');
  const copy = document.createElement('canvas'); copy.width = c.width; copy.height = c.height;
  const ctx = copy.getContext('2d'); ctx.drawImage(c, 0, 0);
  const px = ctx.getImageData(0, 0, c.width, c.height).data, bg = window.ddhgsSplats.clearColour;
  let drawn = 0, best = -1, at = [0, 0];
  for (let i = 0; i < px.length; i += 4) {
    const d = Math.max(Math.abs(px[i] - bg[0]), Math.abs(px[i + 1] - bg[1]), Math.abs(px[i + 2] - bg[2]));
    if (d > 8) drawn += 1;
    if (d > best) { best = d; at = [(i / 4) % c.width, Math.floor(i / 4 / c.width)]; }
  }
  return {fraction: drawn / (px.length / 4), best: at, size: [c.width, c.height], url: copy.toDataURL()}; })()"""
FRAMES = "window.ddhgsSplats.frames"


def wait_frames(dt, count):
    """Waits until the 3D view has drawn `count` more frames."""
    start = dt.evaluate(FRAMES)
    dt.wait_for("%s >= %d" % (FRAMES, start + count), "the 3D view to draw")


def check_splat_view(dt, screenshot):
    """The 3D view: drawn, recoloured by the slider, a spectrum on click."""
    checks = {}
    try:
        dt.wait_for("window.ddhgsSplats && window.ddhgsSplats.ready", "the 3D view")
    except RuntimeError as e:  # the page says why in its note
        raise RuntimeError("%s; its note: %s" % (e, dt.evaluate(
            "document.getElementById('splat-note').textContent")))
    # Without the camera frustums, every pixel that differs is the model's.
    dt.evaluate("document.getElementById('splat-cameras').checked = false")
    dt.evaluate("document.getElementById('sec-3d').scrollIntoView({block: 'start'})")
    deadline = time.time() + TIMEOUT_S  # the depth sort runs in a worker: wait for it
    while True:
        wait_frames(dt, 2)
        before = dt.evaluate(SPLAT_PIXELS)
        if before["fraction"] > 0.01 or time.time() > deadline:
            break
    checks["splat_drawn_fraction"] = before["fraction"]

    # One band, chosen with the wavelength slider by a real click near its left end.
    dt.evaluate("(() => { const s = document.getElementById('splat-mode'); s.value = 'band';"
                " s.dispatchEvent(new Event('input')); })()")
    wait_frames(dt, 3)
    band_mid = dt.evaluate(SPLAT_PIXELS)
    slider_before = dt.evaluate("document.getElementById('splat-band').value")
    left, top, width, height = dt.evaluate(CENTRE % '"#splat-band"')
    dt.click(left + 0.03 * width, top + height / 2)
    dt.wait_for("document.getElementById('splat-band').value !== %s" % json.dumps(slider_before),
                "the 3D view's slider to move")
    wait_frames(dt, 3)
    band_low = dt.evaluate(SPLAT_PIXELS)
    checks["splat_slider_moved"] = [slider_before, dt.evaluate("document.getElementById('splat-band').value")]
    checks["splat_label"] = dt.evaluate("document.getElementById('splat-label').textContent")
    checks["splat_recoloured"] = before["url"] != band_mid["url"] and band_mid["url"] != band_low["url"]

    # The slider is continuous in wavelength: halfway between bands 1 and 2
    # the view is their interpolation, unlike either band.
    def at_nm(expression):
        dt.evaluate("(() => { const s = document.getElementById('splat-band'); s.value = String(%s);"
                    " s.dispatchEvent(new Event('input')); })()" % expression)
        wait_frames(dt, 3)
        return dt.evaluate(SPLAT_PIXELS)["url"], dt.evaluate(
            "document.getElementById('splat-label').textContent")
    wl = "window.DDHGS_REPORT.wavelengths_nm"
    band1, _ = at_nm("%s[1]" % wl)
    band2, _ = at_nm("%s[2]" % wl)
    between, label = at_nm("(%s[1] + %s[2]) / 2" % (wl, wl))
    checks["splat_between_label"] = label
    checks["splat_between_interpolated"] = ("interpolated between band 1" in label
                                            and between not in (band1, band2) and band1 != band2)

    # NDVI colours every splat by (NIR - red) / (NIR + red).
    dt.evaluate("(() => { const s = document.getElementById('splat-mode'); s.value = 'index:ndvi';"
                " s.dispatchEvent(new Event('input')); })()")
    wait_frames(dt, 3)
    checks["splat_ndvi_label"] = dt.evaluate("document.getElementById('splat-label').textContent")
    checks["splat_ndvi_recoloured"] = (checks["splat_ndvi_label"].startswith("NDVI")
                                       and dt.evaluate(SPLAT_PIXELS)["url"] not in (between, band1, band2))
    dt.evaluate("(() => { const s = document.getElementById('splat-mode'); s.value = 'band';"
                " s.dispatchEvent(new Event('input')); })()")
    wait_frames(dt, 3)

    # A click on the most visible splat plots a spectrum.
    left, top, width, height = dt.evaluate(CENTRE % '"#splat-canvas"')
    x, y = band_low["best"]
    dt.click(left + (x + 0.5) * width / band_low["size"][0], top + (y + 0.5) * height / band_low["size"][1])
    dt.wait_for("window.ddhgsSplats.picks > 0", "a pick after the click")
    checks["splat_pick"] = dt.evaluate("window.ddhgsSplats.pick")
    checks["splat_spectrum_points"] = dt.evaluate(
        "window.ddhgsSplats.spectrumChart.data.slice(1).map(s => s.filter(v => v !== null).length)")
    checks["splat_pick_text"] = dt.evaluate("document.getElementById('splat-pick').textContent")
    dt.evaluate("document.getElementById('splat-cameras').checked = true")
    wait_frames(dt, 3)
    dt.evaluate("window.scrollTo(0, 0)")
    rect = dt.evaluate("(() => { const r = document.getElementById('sec-3d').getBoundingClientRect();"
                       " return [r.left + window.scrollX, r.top + window.scrollY, r.width, r.height]; })()")
    shot = dt.send("Page.captureScreenshot", {"format": "png", "captureBeyondViewport": True,
                                              "clip": {"x": rect[0], "y": rect[1], "width": rect[2],
                                                       "height": rect[3], "scale": 1}})
    pathlib.Path(screenshot).write_bytes(base64.b64decode(shot["data"]))
    return checks


def splat_ok(checks, bands):
    pick = checks.get("splat_pick") or {}
    return (checks["splat_drawn_fraction"] > 0.01 and checks["splat_recoloured"]
            and checks["splat_between_interpolated"]
            and checks["splat_ndvi_recoloured"]
            and checks["splat_slider_moved"][0] != checks["splat_slider_moved"][1]
            and pick.get("gaussians", 0) > 0
            and checks["splat_spectrum_points"] == [bands, bands])


# Centre of an element in CSS pixels, scrolled into view first.
CENTRE = """(() => { const e = document.querySelector(%s); e.scrollIntoView({block: 'center'});
  const r = e.getBoundingClientRect(); return [r.left, r.top, r.width, r.height]; })()"""
CANVAS_PIXELS = "document.getElementById(%s).toDataURL()"
SPECTRUM_CANVAS = "document.querySelector('#spectrum canvas').toDataURL()"


def run(chromium, index, screenshot, profile, with_viewer=True):
    checks = {}
    dt = DevTools(chromium, profile)
    try:
        targets = dt.send("Target.getTargets", browser=True)["targetInfos"]
        page = next(t for t in targets if t["type"] == "page")
        dt.session = dt.send(
            "Target.attachToTarget", {"targetId": page["targetId"], "flatten": True}, browser=True
        )["sessionId"]
        for domain in ("Runtime", "Log", "Page"):
            dt.send(domain + ".enable")
        dt.send(
            "Emulation.setDeviceMetricsOverride",
            {"width": 1280, "height": 2000, "deviceScaleFactor": 1, "mobile": False},
        )
        nav = dt.send("Page.navigate", {"url": pathlib.Path(index).resolve().as_uri()})
        if nav.get("errorText"):
            raise RuntimeError("cannot open %s: %s" % (index, nav["errorText"]))
        dt.wait_for("window.ddhgsReady === true", "the report to finish building")
        checks["bands"] = dt.evaluate("window.DDHGS_REPORT.wavelengths_nm.length")
        stem, dot, ext = screenshot.rpartition(".")
        checks.update(check_splat_view(dt, stem + "_3d" + dot + ext))

        if not with_viewer:
            # A report without viewer views (a band-per-view scene): the page
            # says why instead.
            checks["viewer_note"] = dt.evaluate("document.getElementById('spectrum-label').textContent")
            time.sleep(0.2)
            dt.evaluate("1")
            checks["console_errors"] = console_errors(dt.events)
            checks["ok"] = bool(checks["viewer_note"]) and not checks["console_errors"] and splat_ok(
                checks, checks["bands"])
            return checks

        band_before = dt.evaluate(CANVAS_PIXELS % '"canvas-render"')
        slider_before = dt.evaluate("document.getElementById('band-slider').value")
        left, top, width, height = dt.evaluate(CENTRE % '"#band-slider"')
        dt.click(left + 0.97 * width, top + height / 2)  # near the slider's right end
        dt.wait_for("document.getElementById('band-slider').value !== %s" % json.dumps(slider_before),
                    "the slider to move")
        checks["slider_moved"] = [slider_before, dt.evaluate("document.getElementById('band-slider').value")]
        checks["band_label"] = dt.evaluate("document.getElementById('band-label').textContent")
        checks["band_image_changed"] = dt.evaluate(CANVAS_PIXELS % '"canvas-render"') != band_before

        spectrum_before = dt.evaluate(SPECTRUM_CANVAS)
        left, top, width, height = dt.evaluate(CENTRE % '"#canvas-render"')
        dt.click(left + 0.4 * width, top + 0.55 * height)
        dt.wait_for("window.ddhgsViewer.spectraPlotted > 0", "a spectrum after the click")
        spectrum = dt.evaluate(
            "window.ddhgsViewer.spectrumChart.data.slice(1).map(s => s.filter(v => v !== null).length)"
        )
        checks["spectrum_points_per_series"] = spectrum
        checks["spectrum_plot_changed"] = dt.evaluate(SPECTRUM_CANVAS) != spectrum_before
        checks["clicked_pixel"] = dt.evaluate("window.ddhgsViewer.pixel")
        checks["spectrum_label"] = dt.evaluate("document.getElementById('spectrum-label').textContent")

        dt.evaluate("window.scrollTo(0, 0)")
        shot = dt.send("Page.captureScreenshot", {"format": "png", "captureBeyondViewport": True})
        pathlib.Path(screenshot).write_bytes(base64.b64decode(shot["data"]))
        time.sleep(0.2)
        dt.evaluate("1")  # collects events that arrived meanwhile
        checks["console_errors"] = console_errors(dt.events)
    finally:
        dt.close()
    ok = (
        checks["slider_moved"][0] != checks["slider_moved"][1]
        and checks["band_image_changed"]
        and checks["spectrum_plot_changed"]
        and all(n == checks["bands"] for n in checks["spectrum_points_per_series"])
        and len(checks["spectrum_points_per_series"]) >= 2
        and not checks["console_errors"]
        and splat_ok(checks, checks["bands"])
    )
    checks["ok"] = ok
    return checks


def main():
    args = sys.argv[1:]
    with_viewer = "--no-viewer" not in args
    args = [a for a in args if a != "--no-viewer"]
    if len(args) != 4:
        sys.exit(__doc__)
    try:
        checks = run(*args, with_viewer=with_viewer)
    except Exception as e:  # reported as one line the C++ test shows
        checks = {"ok": False, "error": "%s: %s" % (type(e).__name__, e)}
    print(json.dumps(checks))
    sys.exit(0 if checks["ok"] else 1)


if __name__ == "__main__":
    main()
