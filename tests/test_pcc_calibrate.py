"""Paper 003 Sec. V through the calibration engine: ``softrod.calibrate(..., model="pcc")``
fits the PCC model (equilibria and replayed time series in one problem, exact Jacobians)
and ``softrod.pcc.identify_pcc`` runs the paper's staged identification, each stage through
the engine with a closed-form start. The four experiments are made by the PCC model itself
(``softrod.pcc.synthesize_pcc_experiments``, time series driven by their samples joined
linearly, as the engine replays them) from a design with known parameters that differ
from the bundled ones.

The truth: stiff_flop_pcc with k_L = 200 N/m, b_L = 80 N s/m, k_theta = 0.05 N m/rad and
b_theta = 4e-4 N m s/rad, and a 20 g tip body, upright with gravity. b_theta is ten times
smaller than the 0.004 one might pick: the bending mode's inertia J is 9.3e-5 kg m^2 (arm
m L^2/20 plus tip m_t L^2/4), so the damping ratio is b / (2 sqrt(k J)) = 0.11 here, and
0.004 would give 1.1: an overdamped decay without the oscillation that the logarithmic
decrement of the closed-form start needs (paper 003 Sec. V-E; docs/pcc.md doubt 7).
"""

import math

import numpy as np
import pandas as pd
import pytest
import softrod
from conftest import assert_clean_error
from softrod.pcc import identify_pcc, synthesize_pcc_experiments

pytestmark = pytest.mark.fast

TRUTH = {"k_L": 200.0, "k_theta": 0.05, "b_L": 80.0, "b_theta": 4e-4}
UNITS = {"k_L": "N/m", "k_theta": "N*m/rad", "b_L": "N*s/m", "b_theta": "N*m*s/rad"}
TIP_MASS = 0.02  # kg
EXPERIMENTS = {
    "elongation": "1.3 bar",  # Sec. V-B: 0.1-1.3 bar on chambers 1, 3, 5 (here: all six)
    "bending": "1 bar",  # Sec. V-C: one side, up to 138 deg here
    "step": "0.5 bar",
    "free_decay": {"pressure": "0.1 bar", "release": "balanced"},  # 14 deg
}
# Short runs keep the tests fast: the step's slow pole is k_L / b_L = 2.5/s, so 1 s holds
# most of its rise, and the decay's period is 0.33 s, so 1 s holds three swings: both
# parameters shape every sample, which is all a least-squares fit needs (no decrement or
# exponential has to be read off the curve).
DURATION = "1 s"
RATE = 100.0  # Hz
DT = "2 ms"
# Noise-free: the engine replays exactly what synthesised the data (same model, time step
# and commands), so the fit is exact up to the solvers' tolerances (statics and midpoint
# steps to 1e-11 of the coordinate scales) and the optimiser's xtol 1e-10.
EXACT_RTOL = 1e-8
NOISE_MM = 0.1  # an optical tracker's order of accuracy


def _truth_design():
    return softrod.load_design("stiff_flop_pcc").replace(
        {
            **{f"pcc.{k}": f"{v} {UNITS[k]}" for k, v in TRUTH.items()},
            "tip.mass": f"{TIP_MASS} kg",
        }
    )


def _start_design():
    """The design a user would fit: the same arm and tip body, the paper's [pcc] values."""
    return softrod.load_design("stiff_flop_pcc").replace({"tip.mass": f"{TIP_MASS} kg"})


def _data(noise_mm=0.0, seed=1, experiments=EXPERIMENTS, **kw):
    kw = {"duration": DURATION, "rate": RATE, "dt": DT, "levels": 6, **kw}
    return synthesize_pcc_experiments(
        _truth_design(), experiments, noise_mm=noise_mm, seed=seed, **kw
    )


@pytest.fixture(scope="module")
def clean():
    return _data()


def test_synthetic_dataset_says_what_it_is(clean):
    assert clean.synthetic and clean.metadata["seed"] == 1
    assert clean.metadata["true_parameters"]["k_L"] == TRUTH["k_L"]
    assert clean.experiments == ("elongation", "bending", "step", "free_decay")
    assert clean.time is not None and clean.tip_rotation is not None
    step = clean.subset(clean.experiment == "step")
    assert np.all(step.pressures[0] == 0) and np.all(step.pressures[1:] == 0.5e5)
    decay = clean.subset(clean.experiment == "free_decay")
    # One side (chambers 6, 1, 2) at 0.1 bar, released to 0.05 bar on all six: same sum p A.
    assert np.count_nonzero(decay.pressures[0]) == 3
    assert decay.pressures[1:].sum(axis=1) == pytest.approx(3 * 0.1e5)


def test_one_problem_recovers_every_parameter_exactly(clean):
    res = softrod.calibrate(_start_design(), clean, list(TRUTH), model="pcc", dt=DT)
    assert res.model == "pcc" and res.dynamic and res.success
    for name, v in zip(res.names, res.values, strict=True):
        assert v == pytest.approx(TRUTH[name], rel=EXACT_RTOL), name
    # Exact data: the residual is round-off, and the standard errors with it.
    assert res.error_table.max_error_mm.max() < 1e-7
    assert np.all(res.std_errors < 1e-8 * np.array(list(TRUTH.values())))
    # The calibrated design holds the values in [pcc], with provenance.
    seg = softrod.pcc.pcc_parameters(res.design)[0]
    for name in TRUTH:
        assert seg[name] == pytest.approx(TRUTH[name], rel=EXACT_RTOL)
    assert res.design.provenance["tool"] == "softrod.calibrate"
    assert "pcc model" in res.design.assumptions[-1]


def test_staged_identification_starts_from_the_closed_forms(clean):
    res = identify_pcc(_start_design(), clean, dt=DT)
    for name, v in zip(res.names, res.values, strict=True):
        assert v == pytest.approx(TRUTH[name], rel=EXACT_RTOL), name
    stages = res.stages.set_index("parameter")
    assert list(stages.index) == list(TRUTH)  # paper 003's order
    assert list(stages.experiments) == ["elongation", "bending", "step", "free_decay"]
    # The closed forms: the Hookean fit with an offset for the weight is exact for the
    # elongation (theta = 0), the tied two-mode fit for the step up to the midpoint rule;
    # paper 003's M/theta with the chamber moment alone is the stiffness of a weightless arm
    # bending as far: the upright arm's gravity moment makes it about 27 % lower. The
    # engine's stage, with gravity in the model, corrects it.
    assert stages.loc["k_L", "start"] == pytest.approx(TRUTH["k_L"], rel=1e-6)
    assert 0.6 < stages.loc["k_theta", "start"] / TRUTH["k_theta"] < 0.85
    assert stages.loc["k_theta", "stage_value"] == pytest.approx(TRUTH["k_theta"], rel=1e-8)
    assert stages.loc["b_L", "start"] == pytest.approx(TRUTH["b_L"], rel=0.05)
    assert stages.loc["b_theta", "start"] == pytest.approx(TRUTH["b_theta"], rel=0.05)
    closed_forms = ("Hookean", "M / theta", "tied", "logarithmic")
    assert all(s.startswith(closed_forms) for s in stages.start_from)


def test_a_release_to_zero_no_longer_biases_the_damping():
    # Venting every chamber lets the elongation the pressure made creep back (slow pole
    # k_L / b_L = 2.5/s) while the bending decays: J ~ L^2 shrinks and the amplitude grows
    # against it, so the logarithmic decrement (the closed-form start) reads less damping
    # (docs/pcc.md). The engine replays the model, creep included: exact.
    data = _data(experiments={"free_decay": "0.1 bar"}, duration="1.5 s")
    res = identify_pcc(_truth_design(), data, "b_theta", dt=DT)
    start = res.stages.loc[0, "start"]
    assert 0.85 < start / TRUTH["b_theta"] < 0.99
    assert res.values[0] == pytest.approx(TRUTH["b_theta"], rel=EXACT_RTOL)


def test_bending_stiffness_table_in_a_weightless_arm():
    # A k_theta(theta) falling with the angle (paper 003 Fig. 5c) as a table: with degree 1
    # the staged identification builds an 8-entry table over the bending data from the
    # closed form M / theta (exact without gravity), and the engine fits every entry.
    table = {"angle": ["0 deg", "140 deg"], "stiffness": ["0.08 N*m", "0.05 N*m"]}
    truth = softrod.load_design("stiff_flop_pcc").replace(
        {"mounting.gravity": "0 m/s^2", "pcc.k_theta": table}
    )
    data = synthesize_pcc_experiments(truth, {"bending": "1 bar"}, seed=0, levels=12)
    res = identify_pcc(truth, data, "k_theta", degree=1)
    assert res.names == [f"k_theta[{j}]" for j in range(8)]
    angles, k = softrod.pcc.pcc_parameters(res.design)[0]["k_theta"]
    truth_k = np.interp(angles, [0.0, math.radians(140)], [0.08, 0.05])
    np.testing.assert_allclose(k, truth_k, rtol=1e-7)


def test_noisy_round_trips_have_honest_standard_errors():
    """Over 20 noise seeds every value lies within 3 standard errors of the truth, and the
    fraction within 2 is close to 95 %: the standard errors describe the scatter."""
    z = []
    for seed in range(20):
        # Shorter records than above (0.6 s: the step's first 1.5 time constants and two
        # decay swings, sampled at 50 Hz and stepped at 4 ms, 80 steps per decay period;
        # 5 levels per static ramp) keep 20 fits within a few seconds.
        data = _data(
            noise_mm=NOISE_MM, seed=100 + seed, duration="0.6 s", levels=5, rate=50.0, dt="4 ms"
        )
        res = softrod.calibrate(_start_design(), data, list(TRUTH), model="pcc", dt="4 ms")
        fitted = zip(res.names, res.values, res.std_errors, strict=True)
        z += [(v - TRUTH[n]) / s for n, v, s in fitted]
        # Informative: 0.1 mm of tip noise leaves about a per cent or less on each value.
        assert np.all(res.std_errors < 0.02 * np.array(list(TRUTH.values())))
    z = np.abs(np.array(z))
    # 80 z-scores: P(any > 3.5) = 3.7 % for honest errors (and 3 is exceeded with 20 %),
    # so 3.5 bounds the worst; the fraction within 2 is binomial(80, 0.954): >= 0.85 with
    # probability > 99.8 %.
    assert z.max() < 3.5, z.max()
    assert np.mean(z < 2) >= 0.85, np.mean(z < 2)


@pytest.mark.parametrize("suffix", [".csv", ".parquet"])
def test_round_trip_through_files(tmp_path, suffix):
    noisy = _data(noise_mm=NOISE_MM, seed=7)
    path = softrod.write_dataset(noisy, tmp_path / f"pcc{suffix}", units="SI")
    loaded = softrod.load_dataset(path, design=_start_design())
    assert loaded.synthetic and loaded.experiments == noisy.experiments
    from_file = softrod.calibrate(_start_design(), path, list(TRUTH), model="pcc", dt=DT)
    in_memory = softrod.calibrate(_start_design(), noisy, list(TRUTH), model="pcc", dt=DT)
    # In SI units the file holds the very same doubles: the same fit, bit for bit.
    assert list(from_file.values) == list(in_memory.values)
    out = from_file.to_toml(tmp_path / "fitted.toml")
    design = softrod.load_design(out)
    seg = softrod.pcc.pcc_parameters(design)[0]
    for name, v in zip(from_file.names, from_file.values, strict=True):
        assert seg[name] == pytest.approx(v, rel=1e-12)
    assert design.tip_mass == pytest.approx(TIP_MASS)
    assert {p["name"] for p in design.provenance["parameters"]} == set(TRUTH)


def test_static_experiments_alone_and_markers(clean):
    """Only equilibria (k_L, k_theta): no time column needed; markers along the arc work as
    they do for the rod."""
    static = clean.subset(np.isin(clean.experiment, ["elongation", "bending"]))
    res = softrod.calibrate(_start_design(), static, ["k_L", "k_theta"], model="pcc")
    assert not res.dynamic
    np.testing.assert_allclose(res.values, [TRUTH["k_L"], TRUTH["k_theta"]], rtol=EXACT_RTOL)


# --- errors --------------------------------------------------------------------------------------


def test_bad_pcc_input_is_refused(clean):
    d = _start_design()
    with pytest.raises(softrod.InputError, match=r"model = 'fem'.*'cosserat'"):
        softrod.calibrate(d, clean, "k_L", model="fem")
    with pytest.raises(softrod.InputError, match="experiments.*model='pcc' only"):
        softrod.calibrate(d, clean, "c_b", experiments={"step": "dynamic"})
    with pytest.raises(softrod.InputError, match="unknown PCC parameter"):
        softrod.calibrate(d, clean, ["k_L", "c_b"], model="pcc")
    with pytest.raises(softrod.InputError, match="k_phi is 0"):
        softrod.calibrate(d, clean, ["k_L", "k_phi"], model="pcc")
    with pytest.raises(softrod.InputError, match="a constant: calibrate k_theta"):
        softrod.calibrate(d, clean, "k_theta[0]", model="pcc")
    with pytest.raises(softrod.InputError, match="unknown experiment id"):
        softrod.calibrate(d, clean, "k_L", model="pcc", experiments={"nope": "static"})
    with pytest.raises(softrod.InputError, match="'static' or 'dynamic'"):
        softrod.calibrate(
            d,
            clean,
            "k_L",
            model="pcc",
            experiments={
                "elongation": "slow",
                "bending": "static",
                "step": "dynamic",
                "free_decay": "dynamic",
            },
        )
    with pytest.raises(softrod.InputError, match="missing: 'bending'"):
        softrod.calibrate(d, clean, "k_L", model="pcc", experiments={"elongation": "static"})
    static = softrod.Dataset(pressures=clean.pressures[:5], tip_position=clean.tip_position[:5])
    with pytest.raises(softrod.InputError, match="need a time column"):
        softrod.calibrate(d, static, "b_L", model="pcc", dynamic=True)


def test_identify_pcc_refuses_bad_input(clean):
    d = _start_design()
    with pytest.raises(softrod.InputError, match="identifies k_L, k_theta"):
        identify_pcc(d, clean, ["k_L", "k_phi"])
    with pytest.raises(softrod.InputError, match="k_L is fitted here"):
        identify_pcc(d, clean, ["k_L", "b_L"], k_L=200)
    with pytest.raises(softrod.InputError, match=r"experiments\['k_L'\].*unknown experiment"):
        identify_pcc(d, clean, "k_L", experiments={"k_L": "nope"})
    renamed = softrod.Dataset(
        pressures=clean.pressures,
        tip_position=clean.tip_position,
        time=clean.time,
        experiment=np.where(clean.experiment == "step", "s1", clean.experiment),
    )
    with pytest.raises(softrod.InputError, match="say which experiment identifies b_L"):
        identify_pcc(d, renamed, "b_L")
    res = identify_pcc(d, renamed, "b_L", experiments={"b_L": "s1"}, k_L=200, dt=DT)
    assert res.values[0] == pytest.approx(TRUTH["b_L"], rel=EXACT_RTOL)
    three = softrod.Dataset(pressures=np.zeros((3, 3)), tip_position=np.zeros((3, 3)))
    with pytest.raises(softrod.InputError, match="single deformable section"):
        identify_pcc("spa_three_chamber_130mm", three, "k_L")


def test_synthesis_rejects_bad_settings():
    d = _start_design()
    with pytest.raises(softrod.InputError, match="unknown kind"):
        synthesize_pcc_experiments(d, {"twist": "1 bar"})
    with pytest.raises(softrod.InputError, match="needs a pressure"):
        synthesize_pcc_experiments(d, {"step": {"channels": [0]}})
    with pytest.raises(softrod.InputError, match="rate.*integer"):
        synthesize_pcc_experiments(d, {"step": "0.1 bar"}, rate=300)
    with pytest.raises(softrod.InputError, match="channels"):
        synthesize_pcc_experiments(d, {"bending": {"pressure": "1 bar", "channels": [6]}})
    with pytest.raises(softrod.InputError, match="release"):
        synthesize_pcc_experiments(d, {"free_decay": {"pressure": "1 bar", "release": "slow"}})
    with pytest.raises(softrod.InputError, match="pressure"):
        synthesize_pcc_experiments(d, {"elongation": "-1 bar"})


# --- the CLI -------------------------------------------------------------------------------------


def _write_start(tmp_path):
    import tomli_w

    path = tmp_path / "start.toml"
    path.write_text(tomli_w.dumps(_start_design().document), encoding="utf-8")
    return path


def test_cli_identifies_a_dataset_and_writes_the_design(run, clean, tmp_path):
    data = softrod.write_dataset(clean, tmp_path / "pcc.csv", units="SI")
    start = _write_start(tmp_path)
    out = tmp_path / "fitted.toml"
    res = run("pcc-identify", "all", data, "--design", start, "--dt", DT, "--write-design", out)
    assert res.exit_code == 0, res.output
    assert 'k_L = "200 N/m"' in res.output
    assert 'b_L = "80 N*s/m"' in res.output
    seg = softrod.pcc.pcc_parameters(softrod.load_design(out))[0]
    for name in TRUTH:
        assert seg[name] == pytest.approx(TRUTH[name], rel=EXACT_RTOL)
    # The same through softrod calibrate --model pcc (one problem).
    res = run("calibrate", start, data, "--model", "pcc", "--params", "k_L,b_theta", "--dt", DT)
    assert res.exit_code == 0, res.output
    assert "k_L" in res.output and "b_theta" in res.output


def test_cli_dataset_errors(clean, tmp_path):
    from click.testing import CliRunner
    from softrod.cli import main

    data = softrod.write_dataset(clean, tmp_path / "pcc.parquet")
    start = _write_start(tmp_path)
    runner = CliRunner()
    res = runner.invoke(main, ["pcc-identify", "all", str(data)])
    assert_clean_error(res, 2, "--design", "dataset")
    res = runner.invoke(
        main, ["pcc-identify", "all", str(data), "--design", str(start), "--experiment", "step"]
    )
    assert_clean_error(res, 2, "--experiment", "PARAM=ID")
    bad = tmp_path / "fitted.txt"
    res = runner.invoke(
        main, ["pcc-identify", "all", str(data), "--design", str(start), "--write-design", str(bad)]
    )
    assert_clean_error(res, 2, "--write-design", ".toml")
    assert not bad.exists()


def test_cli_array_table_still_works_and_writes_a_design(run, tmp_path):
    # The closed-form helpers on an array CSV (p_Pa, d_m), into a design file.
    area = np.pi * 4e-3**2
    p = np.linspace(1e4, 1e5, 6)
    data = tmp_path / "elong.csv"
    pd.DataFrame({"p_Pa": p, "d_m": 3 * p * area / 200.0}).to_csv(data, index=False)
    out = tmp_path / "arm.toml"
    res = run(
        "pcc-identify",
        "longitudinal-stiffness",
        data,
        "--design",
        "stiff_flop_pcc",
        "--write-design",
        out,
    )
    assert res.exit_code == 0, res.output
    assert 'k_L = "200 N/m"' in res.output and f"wrote {out}" in res.output
    assert softrod.pcc.pcc_parameters(softrod.load_design(out))[0]["k_L"] == pytest.approx(200)
