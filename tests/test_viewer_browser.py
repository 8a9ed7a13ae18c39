"""The viewer in a real browser: headless Chromium (Debian's package, driven by playwright's
Python package through its executable path) loads the page, moves a pressure slider, and
the test checks the server's new solve and the pixels of the redrawn tube.

Skipped (with the reason) only when no Chromium is installed; scripts/test.sh installs it.
Set SOFTROD_FIGURES=1 to also write the screenshots of docs/viewer.md to docs/figures/.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest
from browser_driver import ViewerPage, chromium_path, scene_pixels

CHROMIUM = chromium_path()
pytestmark = pytest.mark.skipif(
    CHROMIUM is None,
    reason="no Chromium installed (Debian: apt-get install chromium; scripts/test.sh does it)",
)
FIGURES = Path(__file__).resolve().parents[1] / "docs" / "figures"
P_MAX = 70e3  # Pa: the paper's range for this actuator (slider 0-70 kPa)


@pytest.fixture(scope="module")
def viewer():
    import softrod

    # No environment map: software WebGL takes seconds to light a frame with it.
    v = softrod.view("spa_three_chamber_130mm", pressure_range=(0, P_MAX), environment_map=False)
    yield v
    v.close()


def test_slider_resolves_and_redraws_the_tube(viewer):
    with ViewerPage(viewer, CHROMIUM) as page:
        left = page.panel_left()
        before = page.wait_rendered()
        drawn = scene_pixels(before, left)
        # Non-empty canvas: the straight tube (42 mm wide, 130 mm long at this camera
        # distance) covers thousands of pixels; a blank scene covers none.
        assert drawn.sum() > 5_000, "the scene shows (almost) nothing"
        solves, tip0 = viewer.solves, viewer.solution.tip_position.copy()

        latency = page.click_slider(0, 0.8)

        # Server side: one new solve at the pressure the click set (80 % of the track, to
        # the slider's 0.1 kPa step and the few pixels of the click position).
        assert viewer.solves == solves + 1
        sol = viewer.solution
        assert sol.converged
        assert sol.pressures[0] == pytest.approx(0.8 * P_MAX, abs=0.02 * P_MAX)
        np.testing.assert_array_equal(sol.pressures[1:], [0.0, 0.0])
        np.testing.assert_array_equal(sol.pressures, viewer.pressures)
        # Chamber 0 sits on +d2 = -y (hanging mount): pressure bends the rod towards +y;
        # ~56 kPa moves the 130 mm tip by some 30 mm.
        assert sol.tip_position[1] - tip0[1] > 0.02

        after = page.screenshot()
        changed = (np.abs(after - before).max(axis=2) > 40) & (scene_pixels(after, left) | drawn)
        # The tube moved: a few thousand pixels of the scene changed (a 30 mm swing of a
        # 42 mm tube), and the change lies where the tube is drawn.
        assert changed.sum() > 2_000
        ys, xs = np.nonzero(drawn)
        cy, cx = np.nonzero(changed)
        assert xs.min() - 50 <= np.median(cx) <= xs.max() + 50
        assert ys.min() - 50 <= np.median(cy) <= ys.max() + 50
        print(
            "\nslider-to-redraw latency (ms): "
            + ", ".join(f"{k} {v:.1f}" for k, v in latency.items())
        )

        if os.environ.get("SOFTROD_FIGURES"):
            viewer.screenshot(FIGURES / "viewer_spa_130mm.png", width=1000, height=700)


def test_server_screenshot_is_a_png_of_the_scene(viewer, tmp_path):
    from PIL import Image

    with ViewerPage(viewer, CHROMIUM) as page:
        page.wait_rendered()
        path = viewer.screenshot(tmp_path / "shot.png", width=320, height=240)
    image = np.asarray(Image.open(path).convert("RGB"))
    assert image.shape == (240, 320, 3)
    # The render is not one flat colour: the tube, the mount and the arrows are in it.
    assert image.reshape(-1, 3).std(axis=0).max() > 10


def test_system_viewer_slider_moves_the_platform():
    """softrod.view_system in the browser: a rod's pressure slider re-solves the system,
    and the redrawn scene changes where the rods and the platform are."""
    import softrod

    with softrod.view_system(
        "two_spa_platform", pressure_range=(0, P_MAX), environment_map=False
    ) as v:
        with ViewerPage(v, CHROMIUM) as page:
            left = page.panel_left()
            before = page.wait_rendered()
            drawn = scene_pixels(before, left)
            # Two 42 mm tubes and the platform cover thousands of pixels.
            assert drawn.sum() > 5_000, "the scene shows (almost) nothing"
            solves, p0 = v.solves, v.solution.platform_position.copy()
            page.click_slider(0, 0.8)  # rod 0, channel 0
            assert v.solves == solves + 1
            sol = v.solution
            assert sol.converged
            assert v.pressures[0][0] == pytest.approx(0.8 * P_MAX, abs=0.02 * P_MAX)
            # ~56 kPa on one actuator tilts and shifts the platform by millimetres.
            assert np.linalg.norm(sol.platform_position - p0) > 2e-3
            after = page.screenshot()
            changed = (np.abs(after - before).max(axis=2) > 40) & scene_pixels(after, left)
            assert changed.sum() > 1_000
