"""Closed-loop tracking: the paper 000 arm (pam_arm_220mm, dynamic model with its Kelvin-Voigt
damping tau = 0.19 s) traces a circle of 30 mm diameter in a horizontal plane, driven at
100 Hz by inverse statics as feed-forward and a PI correction on the tip error
(softrod.TrackingController), and the linearised model's prediction of the tracking error
beside the simulated one.

Writes docs/figures/closed_loop_circle.png (top view, tip error over time, pressures) and
prints the numbers. Run: python examples/closed_loop_circle.py [output folder] [--quick]
(--quick: two periods of a 2 s circle, as the tests run it).
"""

import sys
import time
from pathlib import Path

import numpy as np
import softrod
from softrod.control import TargetPath, TrackingController, predicted_circle_error

DESIGN = "pam_arm_220mm"
CENTRE_PRESSURE = 1.5e5  # Pa in every PAM: the circle's centre is the tip there
RADIUS = 0.015  # m: a circle of 30 mm diameter
BOUNDS = "0:3.6 bar"  # the pressures of paper 000's validation data
RATE = 100.0  # Hz
KP, KI = 1.0, 5.0  # gain on the tip error and its integral (1/s)


def run(period: float = 4.0, periods: int = 3, kp: float = KP, ki: float = KI):
    """Track the circle for ``periods`` periods; return (controller, result, rms of the last
    period in m, the linear model's prediction in m, wall time in s)."""
    design = softrod.load_design(DESIGN)
    centre = softrod.solve_statics(design, [CENTRE_PRESSURE] * 3).tip_position
    path = TargetPath.circle(centre, RADIUS, period, duration=periods * period)
    controller = TrackingController(design, path, rate=RATE, kp=kp, ki=ki, pressure_bounds=BOUNDS)
    start = controller.problem.solve(path.at(0.0))
    t0 = time.perf_counter()
    result = softrod.run_closed_loop(
        design, controller, periods * period, rate=RATE, pressures=start.pressures
    )
    wall = time.perf_counter() - t0
    err = controller.errors(result.trajectory)
    last = result.trajectory.time > (periods - 1) * period
    rms = float(np.sqrt(np.mean(err[last] ** 2)))
    system = softrod.linearise(design, [CENTRE_PRESSURE] * 3, nodes=8)
    predicted = predicted_circle_error(system, RADIUS, period, kp=kp, ki=ki, rate=RATE)
    return controller, result, rms, predicted, wall


def main(argv):
    quick = "--quick" in argv
    args = [a for a in argv if a != "--quick"]
    out_dir = Path(args[0]) if args else Path(__file__).parent.parent / "docs" / "figures"
    controller, result, rms, predicted, wall = run(2.0, 2) if quick else run()
    tr = result.trajectory
    print(
        f"{DESIGN}: circle of {2 * RADIUS * 1e3:.0f} mm diameter, period "
        f"{tr.time[-1] / (2 if quick else 3):.1f} s, control at {RATE:.0f} Hz "
        f"(kp {KP}, ki {KI} 1/s)"
    )
    print(
        f"simulated {tr.time[-1]:.1f} s ({len(tr.time) - 1} steps of {tr.time[1] * 1e3:.0f} ms, "
        f"{len(result.control_time)} inverse solves) in {wall:.2f} s"
    )
    print(
        f"RMS tip error over the last period: {rms * 1e3:.3f} mm; the linearised model "
        f"predicts {predicted * 1e3:.3f} mm"
    )
    ff = np.array([h[3] for h in controller.history])
    print(f"pressures used: {ff.min() / 1e5:.3f} - {ff.max() / 1e5:.3f} bar")
    if not quick:
        *_, rms_ff, predicted_ff, _ = run(kp=0.0, ki=0.0)
        print(
            f"feed-forward alone (kp = ki = 0): {rms_ff * 1e3:.3f} mm (predicted "
            f"{predicted_ff * 1e3:.3f} mm)"
        )
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
        from softrod.control import tracking_plot

        fig = tracking_plot(controller, result, out_dir / "closed_loop_circle.png")
        plt.close(fig)
        print(f"wrote {out_dir / 'closed_loop_circle.png'}")


if __name__ == "__main__":
    main(sys.argv[1:])
