"""Datasets with several mountings (docs/datasets.md, ``mounting``): every fit predicts each
row in its own mounting, or refuses by name; none predicts a row in another mounting than
the one it was measured in."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import softrod
from softrod import InputError
from softrod.calibration import calibrate


def test_a_pcc_fit_of_several_mountings_is_refused_by_name():
    # The PCC model predicts every row in the design's mounting: rows measured hanging
    # and horizontal cannot both be its predictions.
    d = softrod.load_design("stiff_flop_pcc")
    data = softrod.Dataset(
        pressures=np.full((4, d.n_channels), 1e4),
        tip_position=np.zeros((4, 3)),
        mounting=np.array(["hanging", "hanging", "horizontal", "horizontal"]),
    )
    with pytest.raises(InputError) as exc:
        calibrate(d, data, ["k_L"], model="pcc")
    assert exc.value.field == "dataset.mounting"
    assert "one mounting" in str(exc.value)


def test_a_held_tip_fit_of_several_mountings_is_refused_by_name():
    # A held tip's pose is one world point: turning the base to another mounting would
    # hold the tip there too, a different experiment from the one measured.
    from test_calibration_held_tip import _base, _data, _held

    held = _held(_base(), "clamped")
    data = _data(held)
    labels = np.array(["hanging", "horizontal"] * (len(data) // 2) + ["hanging"] * (len(data) % 2))
    mixed = dataclasses.replace(data, mounting=labels)
    with pytest.raises(InputError) as exc:
        calibrate(held, mixed, ["E"])
    assert exc.value.field == "dataset.mounting"
    assert "one world pose" in str(exc.value)


def _two_mountings(design):
    """Two short experiments of the paper 000 arm (noise-free): a pulse hanging, the same
    pulse mounted horizontally (experiments 0 and 1)."""
    from softrod import PressureSchedule
    from softrod.calibration import synthesize_trajectory_dataset

    pulse = PressureSchedule.square_pulses(3, [(0, 2e5, 0.2)], rest=0.2, start=0.05)
    parts = [
        synthesize_trajectory_dataset(
            design.replace({"mounting.orientation": o}), pulse, 0.5, rate=50, seed=k, dt=5e-3
        )
        for k, o in enumerate(("hanging", "horizontal"))
    ]
    return softrod.Dataset(
        pressures=np.vstack([p.pressures for p in parts]),
        tip_position=np.vstack([p.tip_position for p in parts]),
        time=np.concatenate([p.time for p in parts]),
        experiment=np.concatenate([np.full(len(p), k) for k, p in enumerate(parts)]),
        mounting=np.array(["hanging"] * len(parts[0]) + ["horizontal"] * len(parts[1])),
    )


def test_a_dynamic_fit_replays_each_experiment_in_its_mounting():
    # Before, every experiment was replayed in the design's own mounting: the horizontal
    # one hanging, 140 mm off, and tau ran to 190 s. Noise-free data of the truth in both
    # mountings: tau comes back to the fit's tolerance (LM stops within 1e-3 of a
    # standard error, and the standard error of noise-free data is round-off-sized), and
    # the horizontal experiment's tips are the horizontal arm's.
    truth = softrod.load_design("pam_arm_220mm")
    data = _two_mountings(truth)
    start = truth.replace({"dynamics.damping_time": "0.3 s"})
    fit = calibrate(start, data, ["damping_time"], dynamic=True, dt=5e-3)
    assert fit.values[0] == pytest.approx(0.19, rel=1e-6)
    # Every tip within 1 um of the data (the replays are the same runs).
    assert fit.error_table["max_error_mm"].max() < 1e-3


def test_an_experiment_with_two_mountings_is_refused_by_name():
    truth = softrod.load_design("pam_arm_220mm")
    data = _two_mountings(truth)
    mixed = np.array(data.mounting)
    mixed[1] = "horizontal"  # one row of the hanging experiment
    bad = dataclasses.replace(data, mounting=mixed)
    with pytest.raises(InputError) as exc:
        calibrate(truth, bad, ["damping_time"], dynamic=True, dt=5e-3)
    assert exc.value.field == "dataset.mounting"
    assert "one mounting" in str(exc.value)


def test_a_per_sample_identification_of_several_mountings_is_refused_by_name():
    # Before, the horizontal samples were solved hanging: "converged" with 50 mm residuals
    # on noise-free data of the design itself.
    from softrod.calibration import identify_stiffness

    d = softrod.load_design("spa_three_chamber_130mm")
    p = np.array([[20e3, 0, 0], [0, 30e3, 0]])
    parts = [
        softrod.synthesize_dataset(d.replace({"mounting.orientation": o}), p)
        for o in ("hanging", "horizontal")
    ]
    data = softrod.Dataset(
        pressures=np.vstack([x.pressures for x in parts]),
        tip_position=np.vstack([x.tip_position for x in parts]),
        mounting=np.array(["hanging"] * 2 + ["horizontal"] * 2),
    )
    with pytest.raises(InputError) as exc:
        identify_stiffness(d, data)
    assert exc.value.field == "dataset.mounting"
    # One mounting is the design's: identified, every factor 1 on its own data.
    one = identify_stiffness(d, parts[0])
    assert np.nanmax(np.abs(one.sigma - 1.0)) < 1e-6


def test_synthesize_dataset_refuses_several_mountings_by_name():
    # It solves every row with the design as mounted; a row labelled with another
    # orientation would contradict its label in a fit of several mountings.
    d = softrod.load_design("spa_three_chamber_130mm")
    p = np.array([[20e3, 0, 0], [0, 30e3, 0]])
    with pytest.raises(InputError) as exc:
        softrod.synthesize_dataset(d, p, mounting=["hanging", "horizontal"])
    assert exc.value.field == "mounting"
    # One label names the rows (the design as mounted), as a fit of one mounting reads it.
    one = softrod.synthesize_dataset(d, p, mounting="bench")
    assert one.mounting.tolist() == ["bench", "bench"]
