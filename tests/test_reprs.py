"""What a REPL or notebook shows of softrod's objects: one line that tells them apart
(name, inputs with units, the tip in mm, converged or not), not the whole design document
and every array (a static solution's default dataclass repr ran to 30,000 characters)."""

from __future__ import annotations

import numpy as np
import pytest
import softrod
from softrod import TipConstraint, load_design, solve_statics

ARM = "spa_three_chamber_130mm"
# One line in a terminal of two standard widths: long enough for a design name, three
# inputs and a tip position, short enough that no array or document fits.
MAX_REPR = 160


@pytest.fixture(scope="module")
def objects():
    design = load_design(ARM)
    sol = solve_statics(design, [10e3, 0, 0])
    pin = TipConstraint.pinned(["5 mm", "0 mm", "-125 mm"])
    system = softrod.load_system("two_spa_platform")
    return {
        "design": design,
        "tendon design": load_design("prebent_finger_on_table"),
        "solution": sol,
        "tendon solution": solve_statics("prebent_tendon_finger", [20e3], tensions=[1.0]),
        "finger": solve_statics("prebent_finger_on_table", [30e3]),
        "pinned solution": solve_statics(design, [0, 0, 0], tip_constraint=pin),
        "batch": softrod.solve_statics_batch(design, [[10e3, 0, 0], [0, 0, 0]]),
        "system": system,
        "system solution": softrod.solve_system(system),
        "system batch": softrod.solve_system_batch(system, [[[0, 0, 0], [0, 0, 0]]]),
        "system trajectory": softrod.simulate_system(system, None, "4 ms"),
        "workspace": softrod.workspace(design, samples=3),
        "simulation": softrod.Simulation(design),
        "inverse": softrod.solve_inverse(design, sol.tip_position),
    }


def test_every_result_shows_one_short_line(objects):
    for what, obj in [*objects.items(), ("contact", objects["finger"].contact)]:
        text = repr(obj)
        assert len(text) <= MAX_REPR, (what, len(text), text)
        assert "\n" not in text and "array(" not in text, (what, text)


def test_reprs_say_what_tells_results_apart(objects):
    assert repr(objects["design"]) == (
        "Design('spa_three_chamber_130mm', L = 130 mm, 3 sections, 3 channels)"
    )
    assert repr(objects["tendon design"]) == (
        "Design('prebent_finger_on_table', L = 80 mm, 1 section, 1 channel, 1 tendon, 1 obstacle)"
    )
    sol = objects["solution"]
    tip = sol.tip_position * 1e3
    # The tip to 0.01 mm in the solution's own coordinates (0.0 for the x on the axis).
    assert repr(sol) == (
        f"StaticSolution('{ARM}', p = [10, 0, 0] kPa, tip (0.00, {tip[1]:.2f}, "
        f"{tip[2]:.2f}) mm, stable True, {sol.iterations} iterations)"
    )
    assert "T = [1] N" in repr(objects["tendon solution"])
    contact = objects["finger"].contact
    force = np.linalg.norm(contact.total_force[0]) * 1e3
    assert repr(contact) == (
        f"Contact(1 obstacle, force [{force:.4g}] mN, {int(contact.in_contact.sum())} node"
        f"{'s' if contact.in_contact.sum() != 1 else ''} touching, deepest "
        f"{contact.max_penetration * 1e3:.3g} mm)"
    )
    assert "tip pinned, tip (5.00, 0.00, -125.00) mm" in repr(objects["pinned solution"])
    assert repr(objects["batch"]) == f"BatchSolution('{ARM}', 2 rows, 2 converged)"
    assert "2 rods: spa_three_chamber_130mm, spa_three_chamber_130mm" in repr(objects["system"])
    assert repr(objects["system trajectory"]).startswith(
        "SystemTrajectory('two_spa_platform', 3 samples, t = 0 ... 0.004 s"
    )
    assert repr(objects["simulation"]) == f"Simulation('{ARM}', t = 0 s, dt = 2 ms, bdf-alpha)"
    assert ", reached, " in repr(objects["inverse"])


def test_a_failed_solve_says_so():
    # One Newton iteration without continuation cannot reach 70 kPa's bend.
    options = softrod.SolverOptions(max_iter=1, continuation=False)
    failed = solve_statics(ARM, [70e3, 0, 0], check=False, options=options)
    assert not failed.converged
    assert (
        repr(failed) == f"StaticSolution('{ARM}', p = [70, 0, 0] kPa, not converged, 1 iteration)"
    )
    assert np.isnan(failed.tip_position).all()
