"""Datasets with several mountings (docs/datasets.md, ``mounting``): every fit predicts each
row in its own mounting, or refuses by name; none predicts a row in another mounting than
the one it was measured in."""

from __future__ import annotations

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
    mixed = softrod.Dataset(
        pressures=data.pressures,
        tip_position=data.tip_position,
        markers=data.markers,
        marker_s=data.marker_s,
        marker_offset=data.marker_offset,
        mounting=labels,
    )
    with pytest.raises(InputError) as exc:
        calibrate(held, mixed, ["E"])
    assert exc.value.field == "dataset.mounting"
    assert "one world pose" in str(exc.value)
