"""PCC model of paper 003 through the Python API: statics against the Cosserat rod,
dynamics (energy, initial states), shapes and input errors."""

import numpy as np
import pytest
import softrod
from softrod.pcc import pcc_model, pcc_parameters, pcc_shape, run_pcc

SPA = "spa_three_chamber_130mm"


def weightless(name=SPA):
    return softrod.load_design(name).replace({"mounting.gravity": "0 m/s^2", "tip.mass": "0 kg"})


@pytest.mark.parametrize("p", [[50e3, 0, 0], [80e3, 20e3, 0], [30e3, 30e3, 30e3]])
def test_pcc_and_cosserat_agree_for_weightless_unloaded_arc(p):
    # Without gravity and tip load the rod's exact solution is an arc of stretch
    # 1 + sum pA/EA and curvature K_bt^-1 (rho x pA e3): the PCC model with its derived
    # k_L = EA/L0, k_theta = EI/L0 gives the same arc. The residual difference is the
    # rod's RK4 error (16 steps per section, ~1e-9 m here); 1e-7 m leaves a margin.
    d = weightless()
    a = softrod.solve_statics(d, p, model="pcc")
    # 80 kPa is beyond paper 001's 0-70 kPa (the design's operating_range); both models
    # are compared there all the same.
    c = softrod.solve_statics(d, p, on_invalid="ignore")
    assert np.abs(a.tip_position - c.tip_position).max() < 1e-7
    assert np.abs(a.tip_rotation - c.tip_rotation).max() < 1e-6
    # The whole shape is the arc: PCC samples every 1/32 of a section; compare to the rod's
    # curvature (constant along the body).
    body = c.section == 1
    assert np.allclose(a.u[a.section == 1], c.u[body][0], atol=1e-6)
    assert np.all(np.isnan(a.force)) and a.converged


def test_gravity_and_tip_load_make_the_models_differ():
    # With gravity the rod's curvature varies along s, the PCC model's cannot.
    d = softrod.load_design(SPA)
    a = softrod.solve_statics(d, [50e3, 0, 0], model="pcc")
    c = softrod.solve_statics(d, [50e3, 0, 0])
    f = softrod.solve_statics(d, [50e3, 0, 0], model="pcc", tip_force=[0.5, 0, 0])
    assert 1e-4 < np.linalg.norm(a.tip_position - c.tip_position) < 0.02
    assert f.tip_position[0] > a.tip_position[0] + 1e-3  # pushed along +x


def test_run_pcc_conserves_energy_without_damping():
    d = softrod.load_design("stiff_flop_pcc").replace(
        {"pcc.b_L": "0 N*s/m", "pcc.b_theta": "0 N*m*s/rad"}
    )
    n = 300
    q0 = [0.115, 0.5, 0.3]
    qd0 = [0.0, 2.0, 5.0]
    out = run_pcc(d, 1e-3, np.zeros((n + 1, 6)), initial=(q0, qd0))
    assert out["q"].shape == (n + 1, 3) and out["tip_rotation"].shape == (n + 1, 3, 3)
    assert np.allclose(out["q"][0], q0) and np.allclose(out["q_dot"][0], qd0)
    e = out["energy"]
    model = pcc_model(d)
    kinetic = max(
        model.energy(list(x), list(v), [0.0] * 6)[0]
        for x, v in zip(out["x"], out["x_dot"], strict=True)
    )
    # Implicit midpoint: O(dt^2) energy error, measured ~1e-6 of the kinetic energy at
    # dt = 1 ms; 1e-4 leaves a margin and still fails for any first-order or wrong term.
    assert np.ptp(e) < 1e-4 * kinetic


def test_run_pcc_initial_states_and_static_limit():
    d = softrod.load_design("stiff_flop_pcc")
    p = np.zeros((401, 6))
    p[:, [0, 1, 5]] = 0.5e5
    st = softrod.solve_statics(d, p[0], model="pcc")
    out = run_pcc(d, 2.5e-3, p, initial="static", save_every=100)
    assert out["time"].tolist() == pytest.approx([0, 0.25, 0.5, 0.75, 1.0])
    # Starting in equilibrium under constant input: stays there.
    assert np.abs(out["tip_position"] - st.tip_position).max() < 1e-9
    # From rest the damped arm creeps towards the same equilibrium (slow pole k_L/b_L
    # = 2.1 1/s and bending pole k_theta/b_theta = 3 1/s: after 1 s within 15 %).
    out = run_pcc(d, 2.5e-3, p, initial="rest", save_every=400)
    rest = softrod.solve_statics(d, [0] * 6, model="pcc").tip_position
    moved = np.linalg.norm(out["tip_position"][-1] - rest)
    total = np.linalg.norm(st.tip_position - rest)
    assert 0.85 * total < moved < 1.01 * total


def test_pcc_shape_is_the_arc():
    d = weightless()
    s, pos, rot = pcc_shape(d, [0.01, 0, 0, 0.12, 0.8, 0.5, 0.01, 0, 0], n_points=10)
    assert s[0] == 0 and s[-1] == pytest.approx(0.13) and pos.shape == (31, 3)
    # The body's points lie on a circle of radius L/theta in one plane.
    body = pos[10:21]
    centre_dir = np.array([np.cos(0.5), np.sin(0.5), 0.0])
    hanging = rot[10][:, 2]  # base tangent of the body (the caps are straight)
    c = body[0] + 0.12 / 0.8 * (rot[10] @ centre_dir)
    assert np.allclose(np.linalg.norm(body - c, axis=1), 0.15, atol=1e-12)
    assert np.allclose(rot[0], rot[9]) and hanging[2] == pytest.approx(-1.0)


def test_parameters_default_from_rod_and_design_table():
    d = weightless()
    par = pcc_parameters(d)
    body = next(s for s in d.sections() if s["name"] == "body")
    assert par[1]["k_L"] == pytest.approx(body["k_se"][2] / body["length"], rel=1e-12)
    assert par[1]["k_theta"] == pytest.approx(body["k_bt"][1][1] / body["length"], rel=1e-12)
    sf = pcc_parameters("stiff_flop_pcc")[0]
    assert (sf["k_L"], sf["b_L"], sf["k_theta"], sf["b_theta"]) == (246, 119, 0.06, 0.02)


def test_bad_inputs_name_field_value_and_rule():
    d = softrod.load_design("stiff_flop_pcc")
    with pytest.raises(softrod.InputError, match="pressures"):
        run_pcc(d, 1e-3, np.zeros((10, 3)))
    with pytest.raises(softrod.InputError, match="dt"):
        run_pcc(d, 0.0, np.zeros((10, 6)))
    with pytest.raises(softrod.InputError, match="initial"):
        run_pcc(d, 1e-3, np.zeros((10, 6)), initial="moving")
    with pytest.raises(softrod.InputError, match="initial"):
        run_pcc(d, 1e-3, np.zeros((10, 6)), initial=([0.1, 0, 0], [0, 0]))
    with pytest.raises(softrod.InputError, match="model"):
        softrod.solve_statics(d, [0] * 6, model="pc")
    with pytest.raises(softrod.DesignError, match="pcc.k_L"):
        d.replace({"pcc.k_L": "-3 N/m"})
    with pytest.raises(softrod.DesignError, match="pcc.b_L"):
        d.replace({"pcc.b_L": "3 N"})
    with pytest.raises(softrod.DesignError, match="pcc.mass_model"):
        d.replace({"pcc.mass_model": "lumped"})
    with pytest.raises(softrod.DesignError, match="pcc.k_theta"):
        d.replace({"pcc.k_theta": {"angle": [0.0, 0.0], "stiffness": [0.1, 0.1]}})


def test_cli_compare_pcc_and_identify(tmp_path):
    import pandas as pd
    from click.testing import CliRunner
    from softrod.cli import main

    runner = CliRunner()
    fig, table = tmp_path / "cmp.png", tmp_path / "cmp.csv"
    args = ["compare-pcc", "stiff_flop_pcc", "--channels", "5,0,1", "--steps", "3"]
    res = runner.invoke(main, [*args, "--out", str(fig), "--table", str(table)])
    assert res.exit_code == 0, res.output
    ds = softrod.load_dataset(table)  # the dataset schema, channels from 0
    assert set(ds.experiments) == {"weightless", "gravity", "gravity + tip load"}
    weightless = ds.experiment == "weightless"
    assert ds.extra["error_mm"][weightless].max() < 1e-2  # same arc (see above)
    assert ds.metadata["channels"] == [5, 0, 1]
    assert ds.pressures[:, [5, 0, 1]].max() == pytest.approx(1e5)  # --p-max 1 bar
    assert ds.pressures[:, [2, 3, 4]].max() == 0.0
    assert fig.stat().st_size > 0
    res = runner.invoke(
        main, ["compare-pcc", "stiff_flop_pcc", "--channels", "9", "--out", "x.png"]
    )
    assert res.exit_code == 2 and "--channels" in res.output
    # pcc-identify on Hookean data of known k_L = 200 N/m (3 chambers of the design).
    area = np.pi * 4e-3**2
    p = np.linspace(1e4, 1e5, 6)
    data = tmp_path / "elong.csv"
    pd.DataFrame({"p_Pa": p, "d_m": 3 * p * area / 200.0}).to_csv(data, index=False)
    res = runner.invoke(
        main,
        ["pcc-identify", "longitudinal-stiffness", str(data), "--design", "stiff_flop_pcc"],
    )
    assert res.exit_code == 0, res.output
    assert 'k_L = "200 N/m"' in res.output


def test_pcc_statics_that_fails_says_so():
    # One Newton iteration cannot reach the 145 deg bend: with check=False the result is
    # marked unconverged with NaN coordinates; with check=True the error is raised.
    from softrod.errors import ConvergenceError
    from softrod.pcc.statics import solve_pcc_statics

    d = softrod.load_design("stiff_flop_pcc")
    p = [1.5e5, 1.5e5, 0.0, 0.0, 0.0, 1.5e5]
    sol = solve_pcc_statics(d, p, check=False, max_iter=1)
    assert not sol.converged and np.isnan(sol.shooting_unknowns).all()
    with pytest.raises(ConvergenceError):
        solve_pcc_statics(d, p, max_iter=1)
