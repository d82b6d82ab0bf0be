"""Tests of :mod:`pronet.experiments`."""
