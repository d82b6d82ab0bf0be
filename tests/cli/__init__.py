"""Tests of :mod:`pronet.cli`."""
