"""Signals reach inside the native core: Ctrl-C (SIGINT) and SIGTERM sent to a running
``pronet`` end a long Monte Carlo call within about a second, with exit 130 or 143, a
one-line message, no panic or traceback, and nothing half-written left behind; a long
filter pass or mechanization from Python ends as soon."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Callable

import pytest

from pronet import _core
from pronet.recorded import alignment, reading, real

from synthetic_recording import synthetic_recording

#: One strategy, many runs on one thread: one native call of a minute or more.
LONG = ["simulate", "--strategies", "constant", "--runs", "3000", "--threads", "1"]


def stops_at_once(
    calls: dict[str, Callable[[], object]], to: Callable[[], int] | None = None
) -> None:
    """Each call, sent Ctrl-C (SIGINT to this process, or to the thread ``to()``
    names when it is sent) 0.3 s in, raises KeyboardInterrupt within a second of the
    signal. Uninterrupted each takes seconds (more under load); the stop is usually a
    tenth of that, the rest is the input check and copy before the native call, which
    signals wait for."""

    def send() -> None:
        if to is None:
            os.kill(os.getpid(), signal.SIGINT)
        else:
            signal.pthread_kill(to(), signal.SIGINT)

    for name, call in calls.items():
        timer = threading.Timer(0.3, send)
        began = time.monotonic()
        timer.start()
        with pytest.raises(KeyboardInterrupt):
            call()
        took = time.monotonic() - began
        timer.join()
        print(f"{name}: stopped {took - 0.3:.2f} s after the signal")
        assert took - 0.3 < 1.0, f"{name} stopped {took - 0.3:.2f} s after the signal"


@pytest.mark.parametrize(
    ("sig", "code", "word"),
    [(signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated")],
)
def test_a_signal_ends_a_long_native_call_at_once(tmp_path, sig, code, word) -> None:
    out = tmp_path / "res"
    proc = subprocess.Popen(
        [sys.executable, "-c", "import sys, pronet.cli; sys.exit(pronet.cli.main())"]
        + [*LONG, "--out", str(out)],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert proc.stdout is not None
        first = proc.stdout.readline()  # said just before the Monte Carlo starts
        assert first.startswith("scenario paper"), first
        time.sleep(1.0)  # well inside the native call (3000 runs take a minute or more)
        sent = time.monotonic()
        proc.send_signal(sig)
        _, err = proc.communicate(timeout=60)
        took = time.monotonic() - sent
    finally:
        proc.kill()
    assert proc.returncode == code, err
    assert "Traceback" not in err and "Panic" not in err, err
    assert f"{word}; no result folder was written" in err
    # The poll is every 50 ms and a chunk of steps takes milliseconds; the rest is the
    # interpreter shutting down.
    print(f"stopped {took:.2f} s after the signal")
    assert took < 1.5, f"the process took {took:.2f} s to stop"
    assert sorted(p.name for p in tmp_path.iterdir()) == []  # no folder, no lock, no temp


def _pronet(args: list[str], env: dict[str, str]) -> subprocess.Popen[str]:
    return subprocess.Popen(
        [sys.executable, "-c", "import sys, pronet.cli; sys.exit(pronet.cli.main())", *args],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env={**os.environ, **env},
    )


@pytest.mark.parametrize("value", ["100000", "0", "-2", "all", "1e3", str(_core.max_threads() + 1)])
def test_a_thread_count_from_the_environment_is_bounded_like_the_option(tmp_path, value) -> None:
    """RAYON_NUM_THREADS=100000 once built 16,000 threads for 13 minutes on a 0.6 s job
    and ignored SIGTERM: now it is refused as --threads is, before any work, in one
    line naming the variable."""
    began = time.monotonic()
    proc = _pronet([*LONG[:-2], "--out", str(tmp_path / "res")], {"RAYON_NUM_THREADS": value})
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 2, err
    assert err.startswith("pronet: RAYON_NUM_THREADS: ") and len(err.splitlines()) == 1, err
    assert f"1 to {_core.max_threads()}" in err
    assert time.monotonic() - began < 20  # the interpreter's start; no thread is built
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize("source", ["option", "environment"])
def test_sigterm_ends_a_run_on_the_most_threads_allowed_at_once(tmp_path, source) -> None:
    """At the largest thread count either source may give, SIGTERM still ends the
    process within a second and a half."""
    most = str(_core.max_threads())
    args = [*LONG[:-2], "--out", str(tmp_path / "res")]
    if source == "option":
        proc = _pronet([*args, "--threads", most], {})
    else:
        proc = _pronet(args, {"RAYON_NUM_THREADS": most})
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().startswith("scenario paper")
        time.sleep(1.0)
        sent = time.monotonic()
        proc.send_signal(signal.SIGTERM)
        _, err = proc.communicate(timeout=60)
        took = time.monotonic() - sent
    finally:
        proc.kill()
    assert proc.returncode == 143, err
    assert "terminated; no result folder was written" in err
    print(f"{most} threads: stopped {took:.2f} s after the signal")
    assert took < 1.5, f"the process took {took:.2f} s to stop"


def test_ctrl_c_ends_a_long_filter_pass_and_mechanization_at_once() -> None:
    """The other long native calls poll too: Ctrl-C 0.3 s into a filter pass over two
    million IMU samples or the mechanization of eight million (each about 4 s here)
    raises KeyboardInterrupt within a second."""
    import numpy as np

    import pronet

    n = 2_000_000
    imu = np.tile([0.01, 0.0, -9.79, 0.0, 1e-4, 0.0], (n, 1))
    imu_time = np.arange(1, n + 1) * 0.01
    longer = np.tile(imu, (4, 1))
    start = dict(lla0=[0.5, 0.6, -10.0], vel0=[1.0, 0.0, 0.0], rpy0=[0.0, 0.0, 0.3])
    calls = {
        "run_filter": lambda: pronet.run_filter(
            imu,
            imu_time,
            t0=0.0,
            strategy=pronet.Strategy.constant([1e-4] * 3 + [1e-6] * 3),
            **start,
        ),
        "mechanize": lambda: pronet.mechanize(longer, 0.01, **start),
    }
    stops_at_once(calls)


def test_ctrl_c_ends_long_predictions_and_ensemble_steps_at_once() -> None:
    """The frozen nets' ``predict`` over a few hundred thousand windows and an
    ``Ensemble`` stepping hundreds of runs to a far tuning instant (or to its end) poll
    too: Ctrl-C 0.3 s in raises KeyboardInterrupt within a second, and an interrupted
    ensemble refuses further use instead of going on with runs at different steps."""
    import numpy as np

    import pronet
    from pronet.learn.frozen import load_frozen

    net = load_frozen("detrend")
    windows = np.random.default_rng(0).normal(size=(200_000, 200)).astype(np.float32)
    traj = pronet.builtin_trajectory("paper")
    q = [1e-4] * 3 + [1e-6] * 3

    def ensemble() -> pronet.Ensemble:
        return pronet.Ensemble(
            traj,
            q,
            sensors=pronet.SensorConfig(imu_variance=q),
            config=pronet.FilterConfig(),
            n_runs=300,
            tuning_period=1e4,  # one instant beyond the end: a single long advance
        )

    interrupted = ensemble()
    calls = {
        "ConvNet.predict": lambda: net.predict(windows),
        "Ensemble.advance": interrupted.advance,
        "Ensemble.finish": lambda: ensemble().finish(),
    }
    stops_at_once(calls)
    with pytest.raises(ValueError, match="interrupted; create a new Ensemble"):
        interrupted.advance()


def test_ctrl_c_ends_sections_filtered_side_by_side_at_once() -> None:
    """pronet real's sections run on threads, whose native calls signals do not reach:
    each thread stops at its next filter pass (~0.1 s here) instead of finishing its
    section (~3 s for these)."""
    rec = synthetic_recording(seed=1, duration=2400.0, name="long").recording
    pair = (
        alignment.align(rec, alignment.estimate_alignment(rec)),
        alignment.align(rec, alignment.Alignment(how="none")),
    )
    stops_at_once({"run_sections": lambda: real.run_sections([pair] * 4, {}, 1.0, threads=2)})


def test_ctrl_c_taken_by_a_section_thread_ends_the_sections_at_once() -> None:
    """The kernel may hand a process's signal to any thread; Python acts on it in the
    main thread only. Sent to a section thread, it was seen only once a whole section
    was done (3-4 s here): the main thread now waits for the sections in slices."""
    rec = synthetic_recording(seed=1, duration=2400.0, name="long").recording
    pair = (
        alignment.align(rec, alignment.estimate_alignment(rec)),
        alignment.align(rec, alignment.Alignment(how="none")),
    )

    def section_thread() -> int:  # the newest pool's: run_sections'
        pools = [t for t in threading.enumerate() if t.name.startswith("ThreadPoolExecutor")]
        ident = pools[-1].ident
        assert ident is not None
        return ident

    stops_at_once(
        {"run_sections": lambda: real.run_sections([pair] * 4, {}, 1.0, threads=2)},
        to=section_thread,
    )


def test_waiting_in_slices_gives_every_result_and_error_in_order() -> None:
    """The main thread's wait (:mod:`pronet._util.waiting`): values and exceptions come back
    as ``Future.result()`` gives them (a task's own TimeoutError too), in order, and
    leaving early cancels the tasks not yet started."""
    from concurrent.futures import ThreadPoolExecutor

    from pronet._util.waiting import result_of, results_in_order

    def task(i: int) -> int:
        time.sleep({0: 0.12, 3: 0.5}.get(i, 0.0))  # 0: longer than a slice
        if i == 2:
            raise TimeoutError("the task's own")
        return i * i

    with ThreadPoolExecutor(max_workers=1) as pool:
        futures = [pool.submit(task, i) for i in range(6)]
        got = []
        with pytest.raises(TimeoutError, match="the task's own"):
            for value in results_in_order(futures):
                got.append(value)
        assert got == [0, 1]
        assert futures[4].cancelled() and futures[5].cancelled()  # 3 was running
        assert result_of(pool.submit(task, 1)) == 1


def test_the_core_reads_any_memory_layout_alike() -> None:
    """Long inputs are read in place when C-contiguous (no copy while the GIL is held,
    so Ctrl-C is seen at once) and copied otherwise: a Fortran-ordered or strided array
    handed to the binding directly gives the same mechanization."""
    import numpy as np

    from pronet import _core

    rng = np.random.default_rng(3)
    imu = np.tile([0.05, 0.0, -9.79, 0.0, 1e-3, 0.002], (500, 1)) + 1e-3 * rng.standard_normal(
        (500, 6)
    )
    layouts = {
        "fortran": np.asfortranarray(imu),
        "strided": np.repeat(imu, 2, axis=0)[::2],
    }
    start = (np.array([0.5, 0.6, -10.0]), np.array([1.0, 0.0, 0.0]), np.array([0.0, 0.0, 0.3]))
    want = _core.mechanize(imu, 0.01, *start)
    for name, arr in layouts.items():
        assert not arr.flags.c_contiguous, name
        got = _core.mechanize(arr, 0.01, *start)
        for key in ("lla", "vel", "rpy"):
            np.testing.assert_array_equal(got[key], want[key], err_msg=f"{name}: {key}")


def test_ctrl_c_while_sections_are_read_cancels_the_reads_not_started(
    monkeypatch, tmp_path
) -> None:
    """Ctrl-C taken in ``run_real``'s reading loop itself (here: as its progress line
    is printed) cancels the reads not yet started: the reads under way finish (0.5 s
    each, two threads), the other fourteen are never made."""
    from pathlib import Path

    started = []

    def slow_load(path, fmt, **kw):  # an unreadable section, after a while
        started.append(path)
        time.sleep(0.5)
        return "unreadable"

    def on_done(name: str) -> None:
        raise KeyboardInterrupt

    paths = [Path(f"/nowhere/s{i}") for i in range(16)]
    monkeypatch.setattr(real, "select_sections", lambda data, names: paths)
    monkeypatch.setattr(reading, "load_section", slow_load)
    began = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        real.run_real("/nowhere", tmp_path / "out", use_models=False, plots=False, on_done=on_done)
    assert len(started) <= 4, started  # before: all 16, one after the other (4 s)
    assert time.monotonic() - began < 2.0
