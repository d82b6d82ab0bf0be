"""No public call aborts under a memory limit.

Each case runs in a fresh interpreter whose address space is limited (``RLIMIT_AS``) to
what it holds after building its inputs plus a few hundred MiB, then makes a call that
would allocate far more in proportion to one argument. Before the fix each ended in
SIGABRT ("memory allocation of … failed", the core's allocation failure); now the core
estimates the call's peak memory before it allocates and refuses it with a
``ValueError`` naming that argument, the estimate and what is available, and a copy
of an input that does not fit is a ``MemoryError`` (docs/results/performance.md, "Memory").
Every child must exit by itself: a negative return code (a signal) fails the test.
"""

from __future__ import annotations

import os
import re
import subprocess
import sys
import textwrap

import pytest

PRELUDE = """
import resource
import numpy as np
import pronet

PAPER_Q = (1e-4,) * 3 + (1e-6,) * 3


def vm_size():
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith("VmSize:"):
                return int(line.split()[1]) * 1024
    raise RuntimeError("no VmSize")


def limit(headroom):
    cap = vm_size() + headroom
    resource.setrlimit(resource.RLIMIT_AS, (cap, cap))


def stationary(n, dvl_every=None):
    imu = np.tile([0.0, 0.0, -9.79, 0.0, 0.0, 0.0], (n, 1))
    time = 0.01 * np.arange(1, n + 1)
    streams = []
    if dvl_every:
        k = time[dvl_every - 1 :: dvl_every]
        streams = [pronet.Dvl(k, np.zeros((len(k), 3)))]
    return imu, time, streams


def run_filter(imu, time, streams, **kwargs):
    return pronet.run_filter(
        imu, time, streams, t0=0.0, lla0=(0.5, 0.6, 0.0), vel0=(0, 0, 0), rpy0=(0, 0, 0),
        strategy=pronet.Strategy.constant(PAPER_Q), **kwargs
    )
"""


def limited(setup: str, call: str, headroom: int = 300 << 20, timeout: float = 120) -> str:
    """Run ``setup``, limit the address space to what the child then holds plus
    ``headroom`` bytes, run ``call``; what it printed: ``ok``, or the type and message of
    the ``ValueError`` or ``MemoryError`` it raised. AssertionError if the child did not
    exit by itself with code 0 (a signal: an abort)."""
    code = (
        PRELUDE
        + textwrap.dedent(setup)
        + f"\nlimit({headroom})\n"
        + "try:\n"
        + textwrap.indent(textwrap.dedent(call), "    ")
        + "\n    print('ok')\n"
        + "except (ValueError, MemoryError) as exc:\n"
        + "    print(type(exc).__name__, exc)\n"
    )
    done = subprocess.run(
        [sys.executable, "-c", code],
        capture_output=True,
        text=True,
        timeout=timeout,
        env={**os.environ, "RUST_BACKTRACE": "0"},
    )
    assert done.returncode == 0, f"exit {done.returncode}: {done.stderr[-400:]}"
    return done.stdout.strip()


def refused(out: str, arg: str) -> None:
    """``out`` is one line: a ValueError naming ``arg`` with the estimate and the room."""
    assert "\n" not in out, out
    pattern = rf"ValueError {arg}: .* would hold about [\d.]+ [MG]iB of memory, .* more \("
    assert re.match(pattern, out), out


# Before: SIGABRT, "memory allocation of 432000120 bytes failed".
def test_a_ten_hour_pass_smoothed_at_every_epoch_is_refused_naming_output_step() -> None:
    out = limited(
        "imu, time, streams = stationary(3_600_000, dvl_every=20)",
        "run_filter(imu, time, streams, smooth=True)",
        headroom=1 << 30,
    )
    refused(out, "output_step")
    assert "3,600,001 kept epochs" in out and "output_step in seconds" in out


# Before: SIGABRT, "memory allocation of 1895825408 bytes failed".
def test_two_million_covariance_times_are_refused_naming_covariance_time() -> None:
    out = limited(
        "imu, time, streams = stationary(1000)\nasked = np.linspace(0.0, 10.0, 2_000_000)",
        "run_filter(imu, time, streams, covariance_time=asked)",
    )
    refused(out, "covariance_time")
    assert "2,000,000 covariances" in out


# Before: SIGABRT, "memory allocation of 410260144 bytes failed".
def test_a_smoothed_monte_carlo_over_five_hours_is_refused_naming_smooth() -> None:
    out = limited(
        "traj = pronet.trajectory_from_segments([[5 * 3600.0, 0, 0, 0]], lla0=(0.5, 0.6, 0),"
        " speed0=1.0)",
        "pronet.monte_carlo(traj, pronet.Strategy.constant(PAPER_Q), n_runs=2, smooth=True,"
        " threads=2)",
    )
    refused(out, "smooth")
    assert "smoothers under way" in out


# Before: SIGABRT, "memory allocation of 251658240 bytes failed".
def test_a_monte_carlo_recording_every_step_is_refused_naming_record_every() -> None:
    out = limited(
        "traj = pronet.trajectory_from_segments([[3 * 3600.0, 0, 0, 0]], lla0=(0.5, 0.6, 0),"
        " speed0=1.0)",
        "pronet.monte_carlo(traj, pronet.Strategy.constant(PAPER_Q), n_runs=4, record_every=1,"
        " threads=1)",
        headroom=500 << 20,
    )
    refused(out, "record_every")


# Before: SIGABRT, "memory allocation of 2280000120 bytes failed" (both builders).
@pytest.mark.parametrize(
    "call",
    [
        'pronet.builtin_trajectory("paper", dt=330 / 19e6)',
        "pronet.trajectory_from_segments([[190000.0, 0, 0, 0]], lla0=(0.5, 0.6, 0), speed0=1.0)",
    ],
)
def test_a_trajectory_of_too_many_samples_is_refused_naming_dt(call: str) -> None:
    refused(limited("", call, headroom=1 << 30), "dt")


# Before: SIGABRT, "memory allocation of 600000120 bytes failed".
def test_mechanizing_a_huge_array_is_refused_naming_imu() -> None:
    out = limited(
        "imu = np.tile([0, 0, -9.8, 0, 0, 0.0], (5_000_000, 1))",
        "pronet.mechanize(imu, 0.01, (0.5, 0.6, 0), (0, 0, 0), (0, 0, 0))",
        headroom=400 << 20,
    )
    refused(out, "imu")


# Before: SIGABRT, "memory allocation of 166723584 bytes failed".
def test_an_ensemble_of_too_many_runs_is_refused_naming_n_runs() -> None:
    out = limited(
        'traj = pronet.builtin_trajectory("paper")',
        "pronet.Ensemble(traj, PAPER_Q, n_runs=100_000, window=100)",
    )
    refused(out, "n_runs")


# Before: SIGABRT, "memory allocation of 257949696 bytes failed" (the checkpoints' buffer).
def test_a_navigator_whose_lag_window_outgrows_memory_is_refused_naming_lag() -> None:
    out = limited(
        """
        nav = pronet._core.Navigator(
            [pronet.Dvl(np.zeros(0), np.zeros((0, 3)))], config=pronet.FilterConfig(), t0=0.0,
            lla0=(0.5, 0.6, 0), vel0=(0, 0, 0), rpy0=(0, 0, 0),
            strategy=pronet.Strategy.constant(PAPER_Q), lag=1e9, checkpoint_every=1,
        )
        imu, time, _ = stationary(100_000)
        """,
        "nav.imu_block(time, imu)",
    )
    refused(out, "lag")
    assert "checkpoint_every" in out


def test_a_pure_inertial_pass_smoothed_over_hours_is_refused_naming_smooth() -> None:
    # Thinned to one epoch a minute, the smoother still holds the whole pass at once.
    out = limited(
        "imu, time, streams = stationary(720_000)",
        "run_filter(imu, time, streams, smooth=True, output_step=60.0)",
    )
    refused(out, "smooth")
    assert "longest stretch without a reading" in out


# Before: SIGABRT, "memory allocation of 1440000000 bytes failed" (each row's update).
def test_a_stream_of_millions_of_rows_is_refused_naming_streams() -> None:
    out = limited(
        "imu, time, _ = stationary(1000)\nk = np.linspace(0.0, 10.0, 2_000_000)\n"
        "dvl = pronet.Dvl(k, np.zeros((len(k), 3)))",
        'run_filter(imu, time, [dvl], epochs="last")',
        headroom=400 << 20,
    )
    refused(out, "streams")


# Before: SIGABRT after 15 s, "memory allocation of 72000000 bytes failed".
def test_a_monte_carlo_with_a_dvl_at_every_sample_is_refused_naming_n_runs() -> None:
    out = limited(
        "traj = pronet.trajectory_from_segments([[5 * 3600.0, 0, 0, 0]], lla0=(0.5, 0.6, 0),"
        " speed0=1.0)\nsensors = pronet.SensorConfig(dvl_period=0.01)",
        "pronet.monte_carlo(traj, pronet.Strategy.constant(PAPER_Q), sensors=sensors, n_runs=8,"
        " threads=1)",
    )
    refused(out, "n_runs")


# Before: SIGABRT, "memory allocation of 320000000 bytes failed" (the times' copy).
def test_a_stream_whose_copy_does_not_fit_is_a_memory_error() -> None:
    out = limited(
        "k = np.arange(40_000_000.0)\nv = np.zeros((len(k), 3))",
        "pronet.Dvl(k, v)",
    )
    assert out == "MemoryError time: 305.2 MiB do not fit in memory", out


# Before: "ValueError time: expected real numbers of shape (n,) ..., got list": NumPy's
# MemoryError converting the list was taken for numbers that are not real.
def test_a_list_whose_conversion_does_not_fit_is_a_memory_error() -> None:
    out = limited(
        "k = [float(i) for i in range(10_000_000)]", "pronet.Dvl(k, [[0, 0, 0]])", 40 << 20
    )
    assert out.startswith("MemoryError ") and "expected real numbers" not in out, out


# Before: SIGABRT, "memory allocation of 320000000 bytes failed" (the windows' copy).
def test_a_native_regressor_on_more_windows_than_fit_is_a_memory_error() -> None:
    out = limited(
        'from pronet.learn import models\nm = models.load("baseline")\n'
        "w = np.zeros((400_000, m.window), np.float32)",
        "m.predict(w)",
    )
    assert out.startswith("MemoryError windows: ") and "do not fit in memory" in out, out


# Before: SIGABRT, "memory allocation of 400000000 bytes failed" (the offsets' copy).
def test_a_clock_search_over_more_offsets_than_fit_is_refused() -> None:
    out = limited(
        "edges = np.arange(1000.0)\ncum = np.zeros((1000, 3))\ngt_time = np.arange(100.0)\n"
        "gt_step = np.zeros((99, 3))\noffsets = np.zeros(50_000_000)",
        "pronet._core.attitude_increment_costs(edges, cum, gt_time, gt_step, offsets, 1.0)",
    )
    assert out.startswith("MemoryError offsets: "), out
    # With room for the copy, the costs' working memory is refused by the estimate.
    out = limited(
        "edges = np.arange(1000.0)\ncum = np.zeros((1000, 3))\ngt_time = np.arange(100.0)\n"
        "gt_step = np.zeros((99, 3))\noffsets = np.zeros(20_000_000)",
        "pronet._core.attitude_increment_costs(edges, cum, gt_time, gt_step, offsets, 1.0)",
        headroom=400 << 20,
    )
    refused(out, "offsets")


def test_tuning_instants_beyond_memory_are_refused_naming_n_samples() -> None:
    out = limited("", "pronet._core.tuning_instants(2**40, 0.01, 1, 0.01)")
    assert out.startswith("ValueError n_samples: "), out


def peak_mib(setup: str, call: str) -> float:
    """The resident memory [MiB] ``call`` adds at its peak (``VmHWM`` after it less
    ``VmRSS`` before it), run after ``setup`` in a fresh interpreter without a limit."""
    code = (
        PRELUDE
        + textwrap.dedent(setup)
        + "\ndef status(key):\n    with open('/proc/self/status') as f:\n"
        + "        return next(int(l.split()[1]) for l in f if l.startswith(key)) / 1024\n"
        + "before = status('VmRSS:')\n"
        + textwrap.dedent(call)
        + "\nprint(status('VmHWM:') - before)\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    return float(done.stdout)


def stated_mib(out: str) -> float:
    """The estimate [MiB] a refusal states."""
    found = re.search(r"would hold about ([\d.]+) ([MG])iB", out)
    assert found, out
    return float(found[1]) * (1024 if found[2] == "G" else 1)


@pytest.mark.parametrize("kwargs", ["", "smooth=True"])
def test_the_estimate_a_refusal_states_is_the_peak_the_call_holds(kwargs: str) -> None:
    # An hour at 100 Hz with a 5 Hz DVL: refused under a limit of 20 MiB more, run
    # without one; the estimate counts what is allocated, the peak what is written.
    setup = "imu, time, streams = stationary(360_000, dvl_every=20)"
    call = f"run_filter(imu, time, streams, {kwargs})"
    stated = stated_mib(limited(setup, call, headroom=20 << 20))
    measured = peak_mib(setup, call)
    assert 0.95 <= stated / measured <= 1.3, (stated, measured)


def test_what_fits_still_runs_under_the_limit() -> None:
    # Ten minutes smoothed at every epoch (~70 MB): well within the same headroom.
    out = limited(
        "imu, time, streams = stationary(60_000, dvl_every=20)",
        "assert len(run_filter(imu, time, streams, smooth=True).smoothed.lla) == 60_001",
    )
    assert out == "ok"
