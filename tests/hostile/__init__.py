"""Hostile inputs to every public entry point, one test module per package module
(the contract and the hostile values: :mod:`hostile.contract`)."""
