"""Tests of :mod:`pronet.recorded`."""
