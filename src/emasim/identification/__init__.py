"""Calibrating a model against measured traces: the data, IDIM-LS, the output-error fit."""
