"""Tests of :mod:`pronet.learn`."""
