"""The depth's surface reference measured at the surface (:mod:`pronet.recorded.surface`):
readings beside fixes at the surface give the offset of a wrong surface pressure (less
the sensor's depth while the vehicle floats); fixes at depth (USBL) or none leave it,
and say so."""

from __future__ import annotations

import numpy as np
import pytest

from pronet.recorded.surface import surface_offset


def _dive(offset: float, rng: np.random.Generator):
    """10 Hz depth for 300 s: 30 s at the surface, a dive to 10 m, 30 s at the surface
    at the end; a wrong surface pressure adds ``offset`` [m] to every reading (σ 2 cm).
    Fixes at 1 Hz: at the surface with heights near 0, at depth (USBL) at −depth."""
    t = np.arange(0.0, 300.0, 0.1)
    true = np.clip(np.minimum(t - 30.0, 270.0 - t) * 0.2, 0.0, 10.0)
    depth = true + offset + rng.normal(size=t.size) * 0.02
    ft = np.arange(0.0, 300.0, 1.0)
    at = np.interp(ft, t, true)
    height = -at + rng.normal(size=ft.size) * 0.3
    return t, depth, ft, height


def test_readings_beside_surface_fixes_give_the_offset() -> None:
    t, depth, ft, height = _dive(0.057, np.random.default_rng(0))
    s = surface_offset(t, depth, ft)
    assert s.offset == pytest.approx(0.057, abs=0.005) and s.readings > 300
    assert s.span is not None and s.span[0] < 1.0 and s.span[1] > 269.0
    assert "from" in s.note and "readings at the surface" in s.note
    # 5.7 cm of water at 1025 kg/m³: 573 Pa above the standard atmosphere
    assert s.pressure(101_325.0, 1025.0) == pytest.approx(101_325 + 573, abs=60)
    # a sensor 0.2 m below the waterline while the vehicle floats
    floating = surface_offset(t, depth + 0.2, ft, surface_depth=0.2)
    assert floating.offset == pytest.approx(0.057, abs=0.005) and "0.2 m deep" in floating.note


def test_without_surface_fixes_the_reference_stays_and_is_stated() -> None:
    t, depth, ft, height = _dive(0.057, np.random.default_rng(1))
    deep = height < -2.0  # USBL fixes only: at depth
    s = surface_offset(t, depth, ft[deep])
    assert s.offset == 0.0 and s.span is None and "keeps the reader's" in s.note
    assert surface_offset(t, depth, np.empty(0)).offset == 0.0
    assert surface_offset(t, depth, ft, given=-0.02).offset == -0.02
    with pytest.raises(ValueError, match="^surface_offset: must be a finite"):
        surface_offset(t, depth, ft, given=float("nan"))


def test_depth_above_the_sea_is_refused_and_one_atmosphere_deep_is_said() -> None:
    """A pressure in kPa converted as pascals reads −10.06 m whatever the depth (the
    vehicle above the sea): refused in one line. An absolute pressure whose atmosphere
    was never taken off reads 10.1 m deep at the surface: beside USBL fixes (no surface
    reading) it ran with a note that understated it; the note now names the atmosphere.
    A dive that
    never comes shallower than 3 m says nothing of it."""
    t, depth, ft, height = _dive(0.0, np.random.default_rng(2))
    with pytest.raises(ValueError, match=r"^depth: the readings lie a median -\d+\.?\d* m, "
                       r"above the sea surface: a height \(positive up\) for a depth, a "
                       "pressure in kPa or bar"):  # fmt: skip
        surface_offset(t, (101.325 + depth * 1025 * 9.80665e-3 - 101_325) / (1025 * 9.80665), ft)
    deep = height < -2.0
    s = surface_offset(t, depth + 10.08, ft[deep])
    assert s.offset == 0.0 and "keeps the reader's" in s.note
    assert "its shallowest readings are 10.0" in s.note and "about one atmosphere" in s.note
    assert "atmosphere" not in surface_offset(t, depth + 3.0, ft[deep]).note
    assert "atmosphere" not in surface_offset(t, depth, ft[deep]).note


def test_the_report_states_an_offset_taken_off_depths_read_in_metres() -> None:
    """A CSV's depths are metres, with no pressure: the report said "Not in the
    configuration (depth offset +0.061 m from 903 readings ...): no depth from pressure,
    or not recorded" of an offset it had measured and taken off. It now says so."""
    from pronet.recorded.report import pressure_text

    note = "depth offset +0.061 m from 903 readings at the surface beside fixes"
    metres = {"surface_pressure": {"pa": None, "offset_m": 0.061, "source": note}}
    assert pressure_text(metres) == (
        f"None: the depths were read in metres; {note}, taken off every depth reading."
    )
    kept = "no reading at the surface beside a fix: the depth keeps the reader's reference"
    none = {"surface_pressure": {"pa": None, "offset_m": 0.0, "source": kept}}
    assert pressure_text(none) == f"None: the depths were read in metres; {kept}."
    bag = {"surface_pressure": {"pa": 101_934.5, "offset_m": 0.061, "source": note}}
    assert pressure_text(bag) == f"101934.5 Pa, {note}."
    no_depth = {"surface_pressure": {"pa": None, "offset_m": None, "source": "no depth"}}
    assert pressure_text(no_depth).startswith("Not in the configuration (no depth)")
