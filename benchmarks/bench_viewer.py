"""Viewer latency: slider move to redrawn scene, in headless Chromium (a script, not a test).

    python benchmarks/bench_viewer.py          # 25 slider clicks -> results/viewer.json
    python benchmarks/bench_viewer.py --quick  # 7 clicks
    python benchmarks/bench_viewer.py --figures  # also write docs/figures/viewer_*.png
    python benchmarks/bench_viewer.py --designs  # also every bundled design's first slider
    python -c "import bench_viewer; bench_viewer.contact_figure()"  # that figure alone
                                                     # (from benchmarks/)

The viewer of ``spa_three_chamber_130mm`` (sliders 0-70 kPa) in Debian's Chromium, driven by
playwright through the browser's executable path, exactly as tests/test_viewer_browser.py
does (tests/browser_driver.py). Each click on a pressure slider's track is timed in the
page's clock: ``total`` when the first frame that shows the whole new scene reaches the
screen (the frames after the click are read back from the WebGL canvas until they settle;
the first one equal to the settled image was drawn, and is shown at the next animation
frame), ``shown`` when the page has applied the server's update to its panel (the solve
number); and on the server: when the solve started (``server``, same machine's clock), the
Rust solve (``solve``) and building and sending the scene update (``draw``). Medians over the
clicks. Without a GPU the browser renders with SwiftShader (software WebGL), whose frame time
dominates ``total``; ``frame_ms`` is the page's idle animation-frame interval, and
``renderer`` the WebGL renderer the page reports. ``--designs`` adds every bundled design
(its first slider, 1280 x 800). $SOFTROD_CHROMIUM_ARGS adds Chromium flags (e.g. to render on
a GPU; tests/browser_driver.py).
"""

from __future__ import annotations

import os
import statistics
import sys
import time
from pathlib import Path

import softrod

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))
from browser_driver import ViewerPage, chromium_path  # noqa: E402
from common import bench_main, load_average, machine, result_header  # noqa: E402

DESIGN = "spa_three_chamber_130mm"
FIGURES = HERE.parent / "docs" / "figures"


def add_arguments(parser) -> None:
    parser.add_argument("--figures", action="store_true", help="write docs/figures/viewer_*.png")
    parser.add_argument(
        "--designs",
        action="store_true",
        help="also every bundled design: 15 clicks on its first slider at 1280 x 800",
    )


def design_latencies(chromium: str, clicks: int = 15) -> dict:
    """Median latencies (ms) of clicks on the first slider of every bundled design (a
    pressure, a tension or the tip force, in that order), alternating between 20 % and 80 %
    of the track so that every click moves the rod."""
    out = {}
    for name in softrod.bundled_designs():
        viewer = softrod.view(name, environment_map=False)
        try:
            with ViewerPage(viewer, chromium, 1280, 800) as page:
                page.wait_rendered()
                page.click_slider(0, 0.5)  # warm-up: first geometry upload
                rows = [page.click_slider(0, 0.2 if k % 2 else 0.8) for k in range(clicks)]
        finally:
            viewer.close()
        out[name] = {
            **{f"median_{k}_ms": statistics.median(r[k] for r in rows) for k in rows[0]},
            "max_total_ms": max(r["total"] for r in rows),
        }
        print(name, {k: round(v, 2) for k, v in out[name].items()})
    return out


def contact_figure(chromium: str | None = None) -> Path:
    """docs/figures/viewer_finger_on_table.png: the page of the pre-bent finger pressed on
    its table at 30 kPa (the table, the contact force, the tension slider and the panel's
    contact lines), as headless Chromium shows it."""
    chromium = chromium or chromium_path()
    if chromium is None:
        raise SystemExit("no Chromium installed (Debian: apt-get install chromium)")
    path = FIGURES / "viewer_finger_on_table.png"
    viewer = softrod.view("prebent_finger_on_table", environment_map=False)
    try:
        with ViewerPage(viewer, chromium, 1280, 800) as page:
            page.wait_rendered()
            viewer.set_inputs(pressures=[30e3])
            time.sleep(1.0)  # a few software-rendered frames
            page.page.screenshot(path=str(path))
    finally:
        viewer.close()
    return path


def system_figure(chromium: str | None = None) -> Path:
    """docs/figures/viewer_two_spa_platform.png: the page of the two-rod platform with rod
    0's channel 0 at 50 kPa and rod 1's channel 1 at 25 kPa, as headless Chromium shows it."""
    chromium = chromium or chromium_path()
    if chromium is None:
        raise SystemExit("no Chromium installed (Debian: apt-get install chromium)")
    path = FIGURES / "viewer_two_spa_platform.png"
    viewer = softrod.view_system("two_spa_platform", environment_map=False)
    try:
        with ViewerPage(viewer, chromium, 1280, 800) as page:
            page.wait_rendered()
            viewer.set_inputs(pressures=[[50e3, 0, 0], [0, 25e3, 0]])
            time.sleep(1.0)  # a few software-rendered frames
            page.page.screenshot(path=str(path))
    finally:
        viewer.close()
    return path


def run(args) -> dict:
    t_start = time.perf_counter()
    chromium = chromium_path()
    if chromium is None:
        raise SystemExit("no Chromium installed (Debian: apt-get install chromium)")
    info = machine()
    clicks = 7 if args.quick else 25
    out = {}
    for size in ((1280, 800), (800, 600)):
        viewer = softrod.view(DESIGN, pressure_range=(0, 70e3), environment_map=False)
        try:
            with ViewerPage(viewer, chromium, *size) as page:
                page.wait_rendered()
                renderer = page.renderer()
                frame = page.frame_interval_ms()
                page.click_slider(0, 0.5)  # warm-up: first geometry upload
                rows = [
                    page.click_slider(k % 3, 0.1 + 0.8 * ((k * 7) % 11) / 10) for k in range(clicks)
                ]
                if args.figures and size == (1280, 800):
                    viewer.set_inputs(pressures=[60e3, 25e3, 0], tip_force=[0.0, 0.0, 0.0])
                    time.sleep(1.0)
                    viewer.screenshot(FIGURES / "viewer_spa_130mm.png", width=1000, height=700)
                    page.page.screenshot(path=str(FIGURES / "viewer_page.png"))
        finally:
            viewer.close()
        key = f"{size[0]}x{size[1]}"
        out[key] = {
            "renderer": renderer,
            "clicks": clicks,
            "frame_ms": frame,
            **{f"median_{k}_ms": statistics.median(r[k] for r in rows) for k in rows[0]},
            "max_total_ms": max(r["total"] for r in rows),
        }
        print(key, {k: round(v, 2) if isinstance(v, float) else v for k, v in out[key].items()})
    if args.figures:
        contact_figure(chromium)
        system_figure(chromium)
    if args.designs:
        out["designs"] = design_latencies(chromium, 5 if args.quick else 15)
    return {
        **result_header("viewer", args.quick, info, design=DESIGN),
        "browser": chromium,
        "chromium_args": os.environ.get("SOFTROD_CHROMIUM_ARGS", ""),
        **out,
        "load_average_after": load_average(),
        "wall_time_s": time.perf_counter() - t_start,
    }


if __name__ == "__main__":
    raise SystemExit(bench_main(sys.argv[1:], __doc__, "viewer", run, add_arguments))
