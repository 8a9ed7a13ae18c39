"""Driving the softrod viewer in headless Chromium (Debian's package, through playwright's
Python package and the browser's executable path: nothing is downloaded). Used by
tests/test_viewer_browser.py and benchmarks/bench_viewer.py.

Latency probe, in the page's own clock. A capture-phase ``pointerdown`` listener stamps the
click and starts watching frames: after every animation frame (a task queued from the
frame's callbacks runs once the frame's rendering callbacks are done) a reduced copy of the
WebGL canvas is taken (the context keeps its drawing buffer for this: an init script asks
for ``preserveDrawingBuffer``). A MutationObserver notes when the solver panel shows the
next solve number (``shown``: the server's update applied; the new tube and that text come
in one message batch). Once the frames have settled (three equal copies after ``shown``),
the first frame equal to the settled one is the first with the whole new scene (tube, tip
frame, arrows); it reaches the screen at the next animation frame, whose time is ``total``:
click-to-redrawn, the slider-to-redraw latency as the user sees it. This times the pixels,
not a guess of how many frames the page needs.
"""

from __future__ import annotations

import io
import os
import shutil
import time

import numpy as np

# Before any page script: keep the WebGL drawing buffer after a frame so the probe can read
# what the frame drew.
INIT_JS = """
(() => {
  const get = HTMLCanvasElement.prototype.getContext;
  HTMLCanvasElement.prototype.getContext = function (type, attrs) {
    if (type === 'webgl' || type === 'webgl2') {
      attrs = Object.assign({}, attrs || {}, {preserveDrawingBuffer: true});
    }
    return get.call(this, type, attrs);
  };
})();
"""

PROBE_JS = """
() => {
  const S = window.__softrod = {down: null, shown: null, frames: [], watching: false, before: null};
  const small = document.createElement('canvas');
  const ctx2d = small.getContext('2d', {willReadFrequently: true});
  const copy = () => {
    const gl = [...document.querySelectorAll('canvas')]
      .sort((a, b) => b.width * b.height - a.width * a.height)[0];
    small.width = Math.max(1, gl.width >> 2);
    small.height = Math.max(1, gl.height >> 2);
    ctx2d.drawImage(gl, 0, 0, small.width, small.height);
    return ctx2d.getImageData(0, 0, small.width, small.height).data;
  };
  const tick = () => {
    if (!S.watching) return;
    const at = performance.now();
    setTimeout(() => S.frames.push({at, image: copy()}), 0);
    requestAnimationFrame(tick);
  };
  document.addEventListener('pointerdown', () => {
    S.down = performance.now();
    S.shown = null;
    S.frames = [];
    S.before = copy();
    if (!S.watching) { S.watching = true; requestAnimationFrame(tick); }
  }, true);
}
"""

# Resolves when the solver panel shows "solve N" with N >= want and the frames after it
# have settled: {total, shown, frames_after_shown, down_epoch}.
WAIT_DRAWN_JS = """
(want) => new Promise((resolve, reject) => {
  const S = window.__softrod;
  const same = (a, b) => {
    if (a.length !== b.length) return false;
    for (let i = 0; i < a.length; i++) if (a[i] !== b[i]) return false;
    return true;
  };
  const shown = () => {
    const m = document.body.innerText.match(/solve (\\d+):/);
    return m && parseInt(m[1]) >= want;
  };
  const deadline = performance.now() + 10000;
  if (shown()) S.shown = performance.now();
  const obs = new MutationObserver(() => {
    if (S.shown === null && shown()) { S.shown = performance.now(); obs.disconnect(); }
  });
  obs.observe(document.body, {subtree: true, childList: true, characterData: true});
  const poll = () => {
    const f = S.frames;
    const after = S.shown === null ? [] : f.filter((x) => x.at > S.shown);
    if (after.length >= 3) {
      const last = after[after.length - 1].image;
      if (same(after[after.length - 2].image, last) && same(after[after.length - 3].image, last)) {
        const k = f.findIndex((x) => same(x.image, last));
        S.watching = false;
        obs.disconnect();
        if (same(S.before, last)) {
          reject(new Error('the click changed nothing on the canvas'));
          return;
        }
        if (k + 1 >= f.length) { reject(new Error('no frame after the settled one')); return; }
        resolve({total: f[k + 1].at - S.down, shown: S.shown - S.down,
                 down_epoch: performance.timeOrigin + S.down});
        return;
      }
    }
    if (performance.now() > deadline) {
      S.watching = false;
      obs.disconnect();
      reject(new Error('no redraw within 10 s'));
      return;
    }
    setTimeout(poll, 5);
  };
  poll();
})
"""


def chromium_args() -> list[str]:
    """Extra Chromium flags from $SOFTROD_CHROMIUM_ARGS (shell words), e.g. to render WebGL
    on a GPU: ``--use-angle=vulkan --enable-gpu --ignore-gpu-blocklist``. None by default:
    headless Chromium then renders with SwiftShader (software WebGL)."""
    import shlex

    return shlex.split(os.environ.get("SOFTROD_CHROMIUM_ARGS", ""))


def chromium_path() -> str | None:
    """Debian's Chromium (or $SOFTROD_CHROMIUM), or None when none is installed."""
    for candidate in (os.environ.get("SOFTROD_CHROMIUM"), "chromium", "chromium-browser"):
        if candidate:
            path = shutil.which(candidate)
            if path:
                return path
    return None


class ViewerPage:
    """A headless Chromium page on a running viewer (use as a context manager)."""

    def __init__(self, viewer, chromium: str, width: int = 1280, height: int = 800):
        self.viewer = viewer
        self.chromium = chromium
        self.size = (width, height)

    def __enter__(self) -> ViewerPage:
        from playwright.sync_api import sync_playwright

        self._pw = sync_playwright().start()
        self._browser = self._pw.chromium.launch(
            executable_path=self.chromium, headless=True, args=chromium_args()
        )
        w, h = self.size
        self.page = self._browser.new_page(viewport={"width": w, "height": h})
        self.page.add_init_script(INIT_JS)
        # fixedDpr=1: the same state renders to the same pixels (viser otherwise lowers the
        # resolution when frames are slow, as they are in software rendering).
        self.page.goto(self.viewer.url + "/?fixedDpr=1")
        self.page.wait_for_selector(".mantine-Slider-track", timeout=30_000)
        self.page.wait_for_function(
            "() => /solve \\d+:/.test(document.body.innerText)", timeout=30_000
        )
        # The "software WebGL" notice covers the top left of the scene: close it.
        close = self.page.locator(".mantine-Notification-closeButton")
        if close.count():
            close.first.click()
        self.page.evaluate(PROBE_JS)
        return self

    def __exit__(self, *exc) -> None:
        self._browser.close()
        self._pw.stop()

    def wait_rendered(self, timeout: float = 30.0) -> np.ndarray:
        """A screenshot once the scene shows something besides the background."""
        deadline = time.monotonic() + timeout
        while True:
            shot = self.screenshot()
            if scene_pixels(shot, self.panel_left()).sum() > 0 or time.monotonic() > deadline:
                return shot
            time.sleep(0.2)

    def panel_left(self) -> int:
        """x (px) where the control panel starts: the scene is to its left."""
        box = self.page.locator(".mantine-Slider-track").first.bounding_box()
        return int(box["x"] - 120) if box else self.size[0]

    def screenshot(self) -> np.ndarray:
        from PIL import Image

        png = self.page.screenshot()
        return np.asarray(Image.open(io.BytesIO(png)).convert("RGB")).astype(np.int16)

    def renderer(self) -> str:
        """The WebGL renderer the page draws with (the unmasked GPU or software renderer's
        name, e.g. "ANGLE (..., SwiftShader ...)" without a GPU)."""
        return str(
            self.page.evaluate(
                """() => {
                  const gl = document.createElement('canvas').getContext('webgl2')
                    || document.createElement('canvas').getContext('webgl');
                  if (!gl) return 'no WebGL';
                  const ext = gl.getExtension('WEBGL_debug_renderer_info');
                  return ext ? gl.getParameter(ext.UNMASKED_RENDERER_WEBGL)
                             : gl.getParameter(gl.RENDERER);
                }"""
            )
        )

    def frame_interval_ms(self, frames: int = 20) -> float:
        """Median time between animation frames of the idle page (the renderer's frame
        time: ~16.7 ms on a GPU at 60 Hz, far more in software WebGL)."""
        return float(
            self.page.evaluate(
                """(n) => new Promise((resolve) => {
                  const t = [];
                  const step = (now) => {
                    t.push(now);
                    if (t.length > n) {
                      const d = t.slice(1).map((x, i) => x - t[i]).sort((a, b) => a - b);
                      resolve(d[Math.floor(d.length / 2)]);
                    } else requestAnimationFrame(step);
                  };
                  requestAnimationFrame(step);
                })""",
                frames,
            )
        )

    def click_slider(self, index: int, fraction: float) -> dict:
        """Click slider ``index`` at ``fraction`` of its track; wait until the page has drawn
        the re-solved scene. Returns latencies in ms from the click: ``total`` (the new
        frame drawn), ``shown`` (the update applied to the page), ``server`` (the solve
        started on the server; same machine, so the clocks agree to ~1 ms), and the server's
        own ``solve`` and ``draw`` times."""
        want = self.viewer.solves + 1
        track = self.page.locator(".mantine-Slider-track").nth(index)
        box = track.bounding_box()
        self.page.mouse.click(box["x"] + fraction * box["width"], box["y"] + box["height"] / 2)
        out = self.page.evaluate(WAIT_DRAWN_JS, want)
        timing = self.viewer.timings[-1]
        return {
            "total": float(out["total"]),
            "shown": float(out["shown"]),
            "server": 1e3 * timing.at - float(out["down_epoch"]),
            "solve": 1e3 * timing.solve_s,
            "draw": 1e3 * timing.draw_s,
        }


def scene_pixels(image: np.ndarray, panel_left: int, background: int = 245) -> np.ndarray:
    """Mask of the scene's drawn pixels: left of the control panel, not near-white, and not
    the orientation gizmo in the bottom-left corner."""
    mask = (image < background).any(axis=2)
    mask[:, panel_left:] = False
    h = image.shape[0]
    mask[h - 80 :, :80] = False
    return mask
