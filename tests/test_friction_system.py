"""Coulomb friction in a system of rods (docs/contact.md, "Friction in the statics",
"Systems of rods"): two bundled fingers pressing onto their table, their tips clamped to one
platform. The core's tests (crates/softrod-core/tests/suite/friction_system.rs) check the
physics against the lone bar's closed forms and the frictionless system; these check the
Python API: the path and its continuation, batches, the CLI, and bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
import softrod
from click.testing import CliRunner
from friction_designs import MU, two_fingers
from softrod import InputError, SolverOptions
from softrod.cli import main
from softrod.system import solve_system, solve_system_batch


@pytest.fixture(scope="module")
def rough_pair():
    return two_fingers(MU)


@pytest.fixture(scope="module")
def smooth_pair():
    return two_fingers()


def _both(p):
    return [[p], [p]]


def test_a_frictional_system_follows_its_path_and_reports_the_friction(rough_pair):
    sol = solve_system(rough_pair, _both(35e3))
    assert sol.converged and sol.stable is None
    assert sol.friction_state is not None and sol.friction_state.max_elastic_slip > 0
    for r in sol.rods:
        # Each rod's path as a clamped rod's, and the table pulling its tip back (-x)
        # within the Coulomb cone of its normal force.
        assert r.friction_state.tip_constraint == "clamped"
        f = r.contact.friction_force[0]
        n = r.contact.total_force[0] - f
        assert f[0] < 0
        assert np.linalg.norm(f) <= MU * np.linalg.norm(n) * (1 + 1e-9)
    # The fingers are mirror images about the platform's middle: the same friction.
    a, b = (r.contact.friction_force[0] for r in sol.rods)
    assert np.allclose(a, b, rtol=0, atol=1e-9 * np.abs(a).max())
    # A path of increments (the contact-free stretch before the tips land jumped over).
    assert 1 < sol.load_steps and sol.friction_state.pressures == [[35e3], [35e3]]
    assert "two_fingers_on_table" in repr(sol)


def test_released_system_keeps_the_friction_reversed_unlike_the_direct_path(rough_pair):
    pressed = solve_system(rough_pair, _both(50e3))
    back = solve_system(rough_pair, _both(20e3), history=pressed)
    direct = solve_system(rough_pair, _both(20e3))
    fb = back.rods[0].contact.friction_force[0][0]
    fd = direct.rods[0].contact.friction_force[0][0]
    # Released, the tip is held out by the friction reversed (+x); loaded directly, it is
    # pulled in (-x): two equilibria at the same pressure, as for the lone finger.
    assert fb > 0 > fd
    assert np.linalg.norm(back.platform_position - direct.platform_position) > 1e-5
    assert back.friction_state.pressures == [[20e3], [20e3]]


def test_more_increments_follow_the_path_more_closely(rough_pair):
    coarse = solve_system(rough_pair, _both(35e3), options=SolverOptions(friction_steps=5))
    fine = solve_system(rough_pair, _both(35e3))
    # First order in the increment (docs/contact.md): 5 and 80 increments differ, but
    # by a fraction of the friction force, not its sign.
    fc = coarse.rods[0].contact.friction_force[0][0]
    ff = fine.rods[0].contact.friction_force[0][0]
    assert fc != ff and np.sign(fc) == np.sign(ff)
    assert abs(fc - ff) < 0.5 * abs(ff)


def test_frictional_system_batch_rows_are_the_single_solves(rough_pair):
    rows = [_both(20e3), [[35e3], [25e3]]]
    batch = solve_system_batch(rough_pair, rows, threads=2)
    assert batch.converged.all()
    assert not batch.stability_assessed.any()
    for i, p in enumerate(rows):
        single = solve_system(rough_pair, p)
        assert np.array_equal(batch.unknowns[i], single.unknowns)


def test_a_system_no_longer_lands_on_the_half_turn(smooth_pair):
    # Two frictionless fingers at 30 kPa: the continuation's Newton once converged to the
    # tips' half-turned orientation (the orientation error vanishes there too) and the
    # solve was refused; a level off the prescribed orientation's branch is now retried
    # in a shorter step.
    sol = solve_system(smooth_pair, _both(30e3))
    assert sol.converged and sol.stable is True
    for r, sr in zip(sol.rods, smooth_pair.rods, strict=True):
        want = sol.platform_rotation @ sr.attachment_rotation
        assert np.allclose(r.rotation[-1], want, atol=1e-8)


def test_bad_history_and_warm_starts_are_refused_by_name(rough_pair, smooth_pair):
    pressed = solve_system(rough_pair, _both(20e3))
    with pytest.raises(InputError, match="initial"):
        solve_system(rough_pair, _both(30e3), initial=pressed)
    with pytest.raises(InputError, match="history"):
        solve_system(rough_pair, _both(30e3), history=pressed.rods[0])
    smooth = solve_system(smooth_pair, _both(20e3))
    with pytest.raises(InputError, match="history"):
        solve_system(rough_pair, _both(30e3), history=smooth)
    with pytest.raises(InputError, match="history"):
        solve_system(smooth_pair, _both(30e3), history=pressed)
    # Another system's path: its rods are other designs.
    other = two_fingers(0.3)
    with pytest.raises(InputError, match=r"history\.rods\[0\]"):
        solve_system(other, _both(30e3), history=pressed)


def test_cli_solve_system_takes_friction_steps(rough, finger, tmp_path):
    rough.save(tmp_path / "rough.toml")
    finger.save(tmp_path / "smooth.toml")
    pair = two_fingers(MU)

    def mm(v):
        return [f"{x * 1e3:.12g} mm" for x in v]

    for name in ("rough", "smooth"):
        rods = "\n".join(
            f'[[rods]]\ndesign = "{name}.toml"\n'
            f"base_position = {mm(r.design.spec['mounting']['base_position'])}\n"
            f"attachment = {mm(r.attachment)}\n"
            f"attachment_orientation = {np.asarray(r.attachment_rotation).tolist()}\n"
            for r in pair.rods
        )
        origin = mm(pair.platform.position)
        (tmp_path / f"{name}_pair.toml").write_text(
            f'[system]\nname = "{name}_pair"\n\n[platform]\nposition = {origin}\n\n{rods}'
        )
    run = CliRunner().invoke
    args = [
        "solve-system",
        str(tmp_path / "rough_pair.toml"),
        "--pressure",
        "30kPa",
        "--pressure",
        "30kPa",
    ]
    out = run(main, [*args, "--friction-steps", "20", "--json"])
    assert out.exit_code == 0, out.output
    doc = json.loads(out.stdout)  # the note that stability is not assessed: on stderr
    assert "stability not assessed" in out.stderr
    assert doc["stable"] is None and doc["converged"]
    api = solve_system(
        softrod.system.load_system(tmp_path / "rough_pair.toml"),
        _both(30e3),
        options=SolverOptions(friction_steps=20),
    )
    assert np.allclose(doc["platform_position_m"], api.platform_position, rtol=0, atol=1e-12)
    for got, r in zip(doc["rods"], api.rods, strict=True):
        assert np.allclose(got["contact"]["friction_force_N"], r.contact.friction_force, atol=1e-12)
        assert got["contact"]["friction_force_N"][0][0] < 0
    table = run(main, args + ["--friction-steps", "20"])
    assert table.exit_code == 0 and "its friction part" in table.output, table.output
    smooth = ["solve-system", str(tmp_path / "smooth_pair.toml"), "--friction-steps", "20"]
    out = run(main, smooth)
    assert out.exit_code != 0 and "--friction-steps" in out.output


def test_motion_with_friction_starts_from_the_frictionless_rest(rough, finger):
    # In motion friction is regularised: at rest it carries no force, so a run of a held
    # tip or of a system on a rough table starts from the frictionless equilibrium (it
    # once refused to start, its static start being a frictionless solve that saw the
    # friction), then the friction acts as the fingers move.
    from softrod.system_dynamics import simulate_system

    rest = softrod.solve_statics(finger, [20e3])
    hold = {
        "type": "clamped",
        "position": rest.tip_position.tolist(),
        "orientation": rest.rotation[-1].tolist(),
    }
    runs = [
        softrod.simulate(d, lambda t: [20e3 + 5e5 * t], 0.01, tip_constraint=hold)
        for d in (rough, finger)
    ]
    assert np.array_equal(runs[0].tip_reaction_force[0], runs[1].tip_reaction_force[0])
    assert not np.array_equal(runs[0].tip_reaction_force[-1], runs[1].tip_reaction_force[-1])
    pairs = [
        simulate_system(two_fingers(mu), lambda t: _both(20e3 + 5e5 * t), 0.01) for mu in (MU, 0.0)
    ]
    assert np.array_equal(pairs[0].platform_position[0], pairs[1].platform_position[0])
    assert not np.array_equal(pairs[0].platform_position[-1], pairs[1].platform_position[-1])


def test_system_batch_table_has_each_rods_contact_and_no_false_stability(rough_pair, smooth_pair):
    rows = [_both(20e3), _both(35e3)]
    batch = solve_system_batch(rough_pair, rows)
    frame = batch.to_frame()
    for i in range(2):
        single = solve_system(rough_pair, rows[1])
        # The table's last row: the single solve's contact and friction, rod by rod.
        assert np.array_equal(batch.contact_force[i][1], single.rods[i].contact.total_force)
        assert np.array_equal(batch.friction_force[i][1], single.rods[i].contact.friction_force)
        assert (
            frame[f"rod{i}_friction0_fx_N"].iloc[1] == single.rods[i].contact.friction_force[0][0]
        )
        assert frame[f"rod{i}_contact0_fz_N"].iloc[1] > 0
    # Friction has no potential: the stability cells are empty, never False.
    assert frame["stable"].isna().all()
    assert batch.metadata["friction_steps"] == SolverOptions().friction_steps
    # Frictionless: assessed, stable, and contact columns all the same.
    smooth = solve_system_batch(smooth_pair, rows).to_frame()
    assert smooth["stable"].all() and "rod1_contact0_fz_N" in smooth


def test_the_system_figure_shows_the_table_and_the_contacts(rough_pair):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from softrod.system_plots import plot_system
    from test_figures import assert_readable

    sol = solve_system(rough_pair, _both(35e3))
    fig = plot_system(sol)
    try:
        assert_readable(fig)
        table_mm = rough_pair.rods[0].design.spec["obstacles"][0]["point"][2] * 1e3
        for ax in fig.axes[:2]:
            # The table seen edge-on (an infinite line at its height) in the view...
            lines = [ln for ln in ax.get_lines() if type(ln).__name__ == "AxLine"]
            assert lines and ax.get_ylim()[0] < table_mm
            # ... and the fingers' contact points on it.
            dots = [ln for ln in ax.get_lines() if ln.get_marker() == "o"]
            assert dots and all(np.allclose(d.get_ydata(), table_mm, atol=0.3) for d in dots)
        labels = [t.get_text() for t in fig.legends[0].get_texts()]
        assert "contact" in labels and "obstacle (seen edge-on)" in labels
    finally:
        plt.close(fig)
