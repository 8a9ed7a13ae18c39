"""Driving the softrod viewer in headless Chromium (Debian's package, through playwright's
Python package and the browser's executable path: nothing is downloaded). Used by
tests/test_viewer_browser.py and benchmarks/bench_viewer.py.

Latency probe: a capture-phase ``pointerdown`` listener stamps the click; a MutationObserver
waits for the solver panel to show the next solve number (the server sends the new tube and
that text in one message batch, applied together); two animation frames later the frame
with the new geometry has been drawn. click-to-drawn is the slider-to-redraw latency as the
user sees it, in the page's own clock.
"""

from __future__ import annotations

import io
import os
import shutil
import time

import numpy as np

PROBE_JS = """
() => {
  window.__softrod = {down: null, shown: null, drawn: null};
  document.addEventListener('pointerdown', () => {
    window.__softrod.down = performance.now();
    window.__softrod.shown = window.__softrod.drawn = null;
  }, true);
}
"""

# Resolves when the solver panel shows "solve N" with N >= want, two frames later.
WAIT_DRAWN_JS = """
(want) => new Promise((resolve) => {
  const shown = () => {
    const m = document.body.innerText.match(/solve (\\d+):/);
    return m && parseInt(m[1]) >= want;
  };
  const finish = () => {
    window.__softrod.shown = performance.now();
    requestAnimationFrame(() => requestAnimationFrame(() => {
      const s = window.__softrod;
      s.drawn = performance.now();
      resolve({total: s.drawn - s.down, shown: s.shown - s.down,
               down_epoch: performance.timeOrigin + s.down});
    }));
  };
  if (shown()) { finish(); return; }
  const obs = new MutationObserver(() => { if (shown()) { obs.disconnect(); finish(); } });
  obs.observe(document.body, {subtree: true, childList: true, characterData: true});
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
