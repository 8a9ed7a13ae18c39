"""Keep what you make (issue 15, item 3): Design.save, saved stiffness maps and hybrid models,
design files that reference their map, calibrated designs with a new name and provenance."""

import json

import numpy as np
import pytest
import softrod
from conftest import assert_clean_error
from softrod import (
    HybridStiffnessModel,
    InputError,
    StiffnessMap,
    fit_stiffness_map,
    identify_stiffness,
    load_design,
    solve_statics,
    solve_statics_batch,
)
from softrod.catalog import bundled_designs
from softrod.presets import PRESETS
from softrod.stiffness_map import FORMAT_VERSION, load_stiffness_map

SPA = "spa_three_chamber_130mm"
P = np.array([[0.0, 0.0, 0.0], [30e3, 0.0, 0.0], [20e3, 50e3, 10e3], [60e3, 60e3, 60e3]])


def mapped_spa():
    return load_design(SPA).replace({"sections[1].law": {"stiffness_map": True}})


def table_map():
    axes = [np.linspace(0.0, 70e3, 3)] * 3
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1) / 70e3
    g0, g1, g2 = grid[..., 0], grid[..., 1], grid[..., 2]
    sigma = np.stack([0.8 + 0.1 * g0, 1.1 - 0.2 * g1, 1.0 + 0.3 * g2], -1)
    return StiffnessMap.from_table(axes, sigma)


# --------------------------------------------------------------------------- Design.save


@pytest.mark.parametrize("name", bundled_designs() + list(PRESETS))
def test_every_bundled_design_and_preset_round_trips(name, tmp_path):
    design = load_design(name)
    back = load_design(design.save(tmp_path / f"{name}.toml"))
    assert back == design  # the same model: name, texts, SI spec
    assert back.spec == design.spec and back.name == design.name


def test_plain_numbers_are_written_with_their_si_unit(tmp_path):
    # Plain numbers for dimensional entries need a document that says units = "SI"
    # (docs/design-format.md); saving writes each with its SI unit.
    d = load_design(SPA).replace(
        {
            "units": "SI",
            "tip.mass": 0.01,
            "sections[1].chambers[0].angle": 0.5,
            "mounting.base_position": [0, 0, 0.1],
        }
    )
    path = d.save(tmp_path / "d.toml")
    text = path.read_text()
    assert 'mass = "0.01 kg"' in text and 'angle = "0.5 rad"' in text
    assert 'base_position = [ "0.0 m", "0.0 m", "0.1 m",]' in text or '"0.1 m"' in text
    back = load_design(path)
    assert back == d and back.tip_mass == 0.01


def test_save_is_atomic_and_checks_the_suffix(tmp_path, monkeypatch):
    d = load_design(SPA)
    with pytest.raises(InputError, match="must end in .toml"):
        d.save(tmp_path / "d.txt")
    target = tmp_path / "d.toml"
    target.write_text("old")
    import tomli_w

    monkeypatch.setattr(tomli_w, "dumps", lambda doc: (_ for _ in ()).throw(OSError("disk full")))
    with pytest.raises(OSError, match="disk full"):
        d.save(target)
    assert target.read_text() == "old" and sorted(p.name for p in tmp_path.iterdir()) == ["d.toml"]


# --------------------------------------------------------------------------- stiffness maps


@pytest.mark.parametrize(
    "make",
    [table_map, lambda: StiffnessMap.constant((0.9, 1.1, 1.2), 3)],
    ids=["table", "constant"],
)
def test_map_round_trips_exactly(make, tmp_path):
    smap = make()
    path = smap.save(tmp_path / "sigma.json", metadata={"note": "test"})
    doc = json.loads(path.read_text())
    assert doc["format"] == "softrod.stiffness_map" and doc["version"] == FORMAT_VERSION
    assert doc["metadata"] == {"note": "test"}
    back = load_stiffness_map(path)
    assert back.kind == smap.kind and back.n_channels == 3
    np.testing.assert_array_equal(back(P), smap(P))  # the same doubles, bit for bit
    assert StiffnessMap.load(path)(P).tolist() == smap(P).tolist()


def test_maps_of_code_cannot_be_saved(tmp_path):
    smap = StiffnessMap.from_callable(lambda p: np.ones((len(p), 3)), 3)
    with pytest.raises(InputError, match="Python code, not data"):
        smap.save(tmp_path / "x.json")
    assert not (tmp_path / "x.json").exists()


def test_newer_or_foreign_files_are_clear_errors(tmp_path):
    path = table_map().save(tmp_path / "sigma.json")
    doc = json.loads(path.read_text())
    doc["version"] = FORMAT_VERSION + 1
    path.write_text(json.dumps(doc))
    with pytest.raises(InputError, match="newer softrod.*upgrade softrod"):
        load_stiffness_map(path)
    other = tmp_path / "other.json"
    other.write_text('{"weights": [1, 2]}')
    with pytest.raises(InputError, match="not a softrod stiffness map"):
        load_stiffness_map(other)
    broken = tmp_path / "broken.json"
    broken.write_text("{")
    with pytest.raises(InputError, match="not valid JSON"):
        load_stiffness_map(broken)


# --------------------------------------------------------------------------- hybrid models


@pytest.fixture(scope="module")
def hybrid():
    data = softrod.load_dataset("spa130_synthetic").subset(np.arange(72))
    ident = identify_stiffness(SPA, data)
    return fit_stiffness_map(ident, hidden=(12, 10), seed=3)


# The numpy forward pass does the scikit-learn operations (scaling, matrix products, tanh,
# exp), its products summed in a fixed order rather than BLAS's, so it agrees to round-off:
# each of the three layers adds a few ulp, and exp turns an absolute error in log sigma
# into a relative one.
_FORWARD_RTOL = 1e-13


def test_hybrid_map_is_the_networks_in_numpy(hybrid):
    np.testing.assert_allclose(hybrid.stiffness_map(P), hybrid.predict(P), rtol=_FORWARD_RTOL)
    assert hybrid.stiffness_map.kind == "mlp"


def test_hybrid_round_trips_without_pickle(hybrid, tmp_path):
    path = hybrid.save(tmp_path / "hybrid.json")
    doc = json.loads(path.read_text())  # plain JSON: numbers and text, nothing to execute
    assert doc["kind"] == "mlp" and doc["version"] == FORMAT_VERSION
    assert doc["metadata"]["softrod_version"] == softrod.__version__
    back = HybridStiffnessModel.load(path)
    assert back.identification is None and back.design == hybrid.design
    assert back.sections == hybrid.sections and back.settings == hybrid.settings
    assert back.training.equals(hybrid.training)
    np.testing.assert_array_equal(back.test_rows, hybrid.test_rows)
    # The saved networks are the fitted ones: the same map, bit for bit.
    np.testing.assert_array_equal(back.predict(P), hybrid.stiffness_map(P))
    np.testing.assert_array_equal(load_stiffness_map(path)(P), hybrid.stiffness_map(P))
    # A loaded model solves like the fitted one.
    a = solve_statics_batch(hybrid.design, P, stiffness_map=hybrid.stiffness_map)
    b = solve_statics_batch(back.design, P, stiffness_map=back.stiffness_map)
    np.testing.assert_array_equal(a.tip_position, b.tip_position)
    with pytest.raises(InputError, match="no identification"):
        softrod.compare_hybrid(back.design, softrod.load_dataset("spa130_synthetic"), back)


# --------------------------------------------------------------------------- designs with maps


@pytest.mark.parametrize("kind", ["json", "csv"])
def test_design_file_references_its_map(kind, tmp_path, run):
    smap = table_map()
    folder = tmp_path / "model"
    folder.mkdir()
    if kind == "json":
        smap.save(folder / "sigma.json")
    else:
        rows = ["p0_kPa,p1_kPa,p2_kPa,sigma_ext,sigma_bend_x,sigma_bend_y"]
        axes = smap.axes
        for i, a in enumerate(axes[0]):
            for j, b in enumerate(axes[1]):
                for k, c in enumerate(axes[2]):
                    cells = [a / 1e3, b / 1e3, c / 1e3, *smap.values[i, j, k]]
                    rows.append(",".join(repr(float(x)) for x in cells))
        (folder / "sigma.csv").write_text("\n".join(rows) + "\n")
    doc = dict(mapped_spa().document)
    doc["stiffness_map"] = {"file": f"sigma.{kind}"}  # relative to the design file
    import tomli_w

    design_path = folder / "mapped.toml"
    design_path.write_text(tomli_w.dumps(doc))
    d = load_design(design_path)
    assert d.stiffness_map is not None and d.stiffness_map_source == folder / f"sigma.{kind}"
    explicit = solve_statics_batch(mapped_spa(), P, stiffness_map=smap)
    # Every API path uses the design's map.
    batch = solve_statics_batch(d, P)
    np.testing.assert_allclose(batch.tip_position, explicit.tip_position, rtol=0, atol=1e-15)
    single = solve_statics(d, P[2])
    np.testing.assert_array_equal(single.stiffness_scale, smap(P[2]))
    # The command line too (from another folder: the path is the design file's).
    res = run("solve", design_path, "--pressure", "20,50,10kPa", "--json")
    assert res.exit_code == 0, res.output
    tip = np.array(json.loads(res.stdout)["tip_position_m"])
    np.testing.assert_allclose(tip, single.tip_position, rtol=0, atol=1e-15)
    # Saved elsewhere, the reference is rewritten relative to the new file.
    other = tmp_path / "elsewhere"
    other.mkdir()
    moved = load_design(d.save(other / "copy.toml"))
    assert moved == d and moved.stiffness_map_source == d.stiffness_map_source
    assert f'file = "../model/sigma.{kind}"' in (other / "copy.toml").read_text()


def test_calibrate_uses_the_designs_map(tmp_path):
    smap = table_map()
    smap.save(tmp_path / "sigma.json")
    d = mapped_spa().with_stiffness_map(tmp_path / "sigma.json")
    truth = d.replace({"sections[1].c_b": 1.2})
    data = softrod.synthesize_dataset(truth, P, noise_mm=0.0, seed=1)
    res = softrod.calibrate(d, data, ["c_b"])
    # Noise-free data of the same design and map: recovered to the fit's tolerances.
    assert res.values[0] == pytest.approx(1.2, rel=1e-6)
    with pytest.raises(InputError, match="stiffness map"):
        softrod.calibrate(d, data, ["sigma_ext"])


def test_map_reference_errors(tmp_path):
    doc = dict(mapped_spa().document)
    doc["stiffness_map"] = {"file": str(tmp_path / "missing.json")}
    with pytest.raises(softrod.DesignError, match="no such file") as exc:
        load_design(doc)
    assert exc.value.field == "stiffness_map.file"  # the design's key (docs/stiffness-map.md)
    table_map().save(tmp_path / "sigma.json")
    plain = dict(load_design(SPA).document)
    plain["stiffness_map"] = {"file": str(tmp_path / "sigma.json")}
    with pytest.raises(softrod.DesignError, match="no section sets"):
        load_design(plain)
    doc["stiffness_map"] = {"file": str(tmp_path / "sigma.json"), "method": "linear"}
    with pytest.raises(softrod.DesignError, match="applies to CSV tables"):
        load_design(doc)


def test_simulate_needs_the_map_of_a_mapped_design():
    # sigma is never assumed to be 1: a mapped design simulates with its map (evaluated in
    # the core at every step's pressures) or not at all.
    with pytest.raises(InputError, match="pass stiffness_map="):
        softrod.simulate(mapped_spa(), [0.0, 0.0, 0.0], 0.01)
    traj = softrod.simulate(
        mapped_spa(), [20e3, 0.0, 0.0], 0.02, dt=0.01, stiffness_map=table_map(), progress=False
    )
    assert np.all(np.isfinite(traj.tip_position))


# --------------------------------------------------------------------------- calibrated designs


def test_calibrated_design_has_a_new_name_and_provenance(tmp_path):
    data = softrod.load_dataset("paper002_m3_synthetic").subset(np.arange(0, 240, 6))
    res = softrod.calibrate("paper002_M3_vertical", data, ["c_b", "offset_1"])
    assert res.design.name == "paper002_M3_vertical_calibrated"
    path = res.to_toml(tmp_path / "cal.toml")
    back = load_design(path)
    assert back == res.design
    prov = back.provenance
    assert prov["tool"] == "softrod.calibrate" and prov["initial_design"] == "paper002_M3_vertical"
    assert prov["dataset"] == "paper002_m3_synthetic.csv" and prov["synthetic_data"] is True
    assert [p["name"] for p in prov["parameters"]] == ["c_b", "offset_1"]
    assert prov["parameters"][1]["unit"] == "m"
    np.testing.assert_array_equal([p["value"] for p in prov["parameters"]], res.values)
    np.testing.assert_array_equal([p["std_error"] for p in prov["parameters"]], res.std_errors)
    # The sentence in the assumptions shows the offset in mm, as every display does.
    assert "offset_1 = " in back.assumptions[-1] and " mm " in back.assumptions[-1]
    named = softrod.calibrate("paper002_M3_vertical", data, ["c_b"], name="rig_b_2024")
    assert named.design.name == "rig_b_2024"
    # One display unit per kind: the offset in mm in the summary and in the report, as on
    # the command line (SI in the arrays, the parameter table and the file).
    line = next(x for x in str(res).splitlines() if x.strip().startswith("offset_1"))
    assert f"{res.values[1] * 1e3:.6g} +- " in line and " mm (" in line
    html = res.write_report(tmp_path / "r.html").read_text()
    assert "Rules: warnings when a relative standard error exceeds 20 %" in html
    assert "<td>mm</td>" in html and res.parameter_table()["unit"].tolist() == ["1", "m"]


def test_calibrate_cli_name_and_predictions(run, tmp_path):
    out, pred = tmp_path / "cal.toml", tmp_path / "pred.csv"
    res = run(
        "calibrate", "spa_three_chamber_130mm", "spa130_synthetic", "--params", "c_b",
        "--split", "experiment", "--name", "spa_rig", "--out", out, "--predictions", pred,
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    assert load_design(out).name == "spa_rig"
    ds = softrod.load_dataset(pred)
    assert ds.metadata["design"] == "spa_rig" and ds.metadata["generator"] == "softrod.calibrate"
    assert set(ds.extra["set"]) == {"train", "test"} and ds.extra["converged"].all()
    measured = softrod.load_dataset("spa130_synthetic")
    np.testing.assert_allclose(ds.tip_position, measured.tip_position, rtol=1e-15)
    model = np.column_stack([ds.extra[f"model_tip_{a}_mm"] for a in "xyz"]) / 1e3
    err = np.linalg.norm(model - measured.tip_position, axis=1) * 1e3
    np.testing.assert_allclose(ds.extra["error_mm"], err, rtol=1e-12)
    res = run("calibrate", SPA, "spa130_synthetic", "--params", "c_b", "--predictions", "p.txt")
    assert_clean_error(res, 2, "--predictions", ".csv")
