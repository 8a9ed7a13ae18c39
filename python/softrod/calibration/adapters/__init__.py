"""Model adapters of the calibration engine: each maps parameter values to the predicted
positions of a dataset's rows with exact parameter Jacobians (see
:class:`softrod.calibration.problem.ModelAdapter`).

- :mod:`.rod_static`: Cosserat-rod equilibria (tip and markers), derivatives by the implicit
  function theorem on the shooting solve (``Rod.sensitivity_batch``);
- :mod:`.rod_dynamic`: Cosserat-rod time series replayed (paper 000);
- :mod:`.pcc`: paper 003's PCC model, equilibria and time series.
"""
