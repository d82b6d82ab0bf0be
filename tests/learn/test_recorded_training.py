"""Learning Q from sections with ground truth: the training sections, the
core's scores, the per-section best constant, model (a)'s fit and model file, the
leave-one-out protocol and its ledger, and model (b)'s Kalman-informed loss through
the torch filter (equal to the same loss taken from the core's pass) and training."""

from __future__ import annotations

import json
import math
import os
import socket
import subprocess
import sys
import tracemalloc

import numpy as np
import pytest
import torch
from recorded.test_real import SNAPIR

from pronet import _core, cli
from pronet.experiments.qlearn.protocol import (
    BEST_CONSTANT,
    CONSTANT,
    ORACLE,
    Ledger,
    cross_validate,
    fit_section_scale,
    gain_share,
    scale_scorer,
)
from pronet.experiments.qlearn.scoring import (
    ScaleGrid,
    constant_metrics,
    paired_rows,
    scale_grid,
    scaled_q,
    score,
)
from pronet.experiments.qlearn.sections import (
    SIM_BYTES_PER_SAMPLE,
    recorded_sections,
    simulated_section,
    simulated_sections,
)
from pronet.learn import modelfile
from pronet.learn.qmodels import SectionScale, load_model_file
from pronet.recorded.tuning import real_strategies
from pronet.strategies import StrategySpec, strategy


@pytest.fixture(scope="module")
def short() -> list:
    """Three 30 s simulated regimes recordings."""
    return simulated_sections(3, seed=7, duration=30.0)


def test_a_simulated_section_carries_its_noise_schedule_and_truth():
    ts = simulated_section(3, duration=120.0)
    s = ts.section
    assert s.imu.shape == (12000, 6) and np.all(np.diff(s.imu_time) > 0)
    assert s.truth_time[0] == 0.0 and np.allclose(np.diff(s.truth_time), 1.0)
    assert len(s.dvl) == len(s.truth_time) - 1
    # the DVL reads the truth's body velocity up to its (0.02 m/s)² noise
    assert ts.oracle_time is not None and ts.oracle_q is not None
    # each piece of the schedule shows in the samples' first differences (var/2 = q)
    t0, t1 = ts.oracle_time[0], ts.oracle_time[1] if len(ts.oracle_time) > 1 else 120.0
    inside = (s.imu_time > t0 + 1) & (s.imu_time < min(t1, 120.0) - 1)
    measured = np.var(np.diff(s.imu[inside], axis=0), axis=0) / 2
    assert np.allclose(measured[3:], ts.oracle_q[0, 3:], rtol=0.2)  # gyros: no motion


def test_a_constant_schedule_scores_as_the_constant_row_and_scales_multiply_groups(short):
    ts = short[0]
    q = np.array(ts.q_nominal)
    assert np.allclose(scaled_q(q, (2.0, 0.5)), q * [2, 2, 2, 0.5, 0.5, 0.5])
    row = constant_metrics(ts)
    same = score(ts, [ts.section.imu_time[0]], [q])
    assert same.srmse == pytest.approx(row.srmse, rel=1e-12)
    worse = constant_metrics(ts, (1e4, 1e4))  # a wildly mistuned q is seen
    assert worse.srmse != pytest.approx(row.srmse, rel=1e-3)


def test_the_best_constant_is_the_grid_minimum_and_model_a_minimises_the_mean_loss():
    log10 = np.array([-1.0, 0.0, 1.0])
    a = ScaleGrid("a", log10, np.array([[3, 2, 3], [2, 1, 2], [3, 2, 3]], float), np.ones((3, 3)))
    b = ScaleGrid("b", log10, np.array([[1, 9, 9], [9, 9, 9], [9, 9, 5]], float), np.ones((3, 3)))
    assert a.best()[:3] == (1.0, 1.0, 1.0)
    assert b.best()[:2] == pytest.approx((0.1, 0.1))
    # sums of squares: a's best (the centre) 1 + 81 = 82, b's other corner 9 + 25 = 34,
    # the corner (0.1, 0.1) 9 + 1 = 10: the least over both, neither's own best
    assert fit_section_scale([a, b]).scales == pytest.approx((0.1, 0.1))


def test_the_ledger_scores_a_test_set_once(tmp_path):
    ledger = Ledger(tmp_path / "sub" / "ledger.jsonl")
    ledger.claim("a", "LOSO x,y 123")
    ledger.claim("a", "held-out y 456")
    ledger.claim("cnn", "LOSO x,y 123")
    with pytest.raises(ValueError, match="already scored on 'LOSO x,y 123'"):
        ledger.claim("a", "LOSO x,y 123")
    assert len(ledger.entries()) == 3


def test_leave_one_out_never_trains_on_the_scored_section(short, tmp_path):
    seen: dict[str, list[str]] = {}

    def trainer(train, grids):
        names = [t.name for t in train]
        assert [g.name for g in grids] == names
        model = SectionScale((1.0, 1.0))
        seen[str(len(seen))] = names
        return model

    ev = cross_validate(short, {"probe": (trainer, scale_scorer)}, ledger=Ledger(tmp_path / "l"))
    names = [t.name for t in short]
    assert sorted(ev.rows["probe"]) == sorted(names)
    for k, name in enumerate(names):  # fold k trained on every section but the k-th
        assert seen[str(k)] == [n for n in names if n != name]
    # the unit-scale probe is the constant row; the best constant is at most it
    for n in names:
        assert ev.rows["probe"][n].srmse == pytest.approx(ev.rows[CONSTANT][n].srmse, rel=1e-12)
        assert ev.rows[BEST_CONSTANT][n].srmse <= ev.rows[CONSTANT][n].srmse
    probe = next(p for p in paired_rows(ev.rows, CONSTANT) if p.label == "probe")
    assert probe.d_srmse.mean == pytest.approx(0.0, abs=1e-15)
    # 30 s never leave the schedule's first regime: the oracle is the constant row
    for n in names:
        assert ev.rows[ORACLE][n].srmse == pytest.approx(ev.rows[CONSTANT][n].srmse, rel=1e-12)
    assert math.isnan(gain_share(ev.rows, ORACLE))
    with pytest.raises(ValueError, match="already scored"):  # the same again: refused
        cross_validate(short, {"probe": (trainer, scale_scorer)}, ledger=Ledger(tmp_path / "l"))


def test_model_a_is_a_model_file_run_natively_by_learned_path(tmp_path):
    path = tmp_path / "scale"
    SectionScale((3.0, 0.01)).save(path, {"training": {"sections": ["x"]}})
    model = load_model_file(path)
    assert isinstance(model, SectionScale) and model.scales == pytest.approx((3.0, 0.01))
    q = (1e-4,) * 3 + (1e-6,) * 3
    row = strategy(StrategySpec.parse(f"learned:{path}"), q)
    assert isinstance(row, _core.Strategy) and row.kind == "constant"
    assert np.allclose(row.q, [3e-4] * 3 + [1e-8] * 3)
    rows = real_strategies(q, {f"learned:{path}": model}, 1.0)
    assert np.allclose(rows[f"learned:{path}"].q, row.q)
    weights, _ = modelfile.paths(path)
    weights.write_bytes(weights.read_bytes()[:-3])  # truncated: named, refused
    with pytest.raises(modelfile.ModelFileError, match="scale.safetensors"):
        load_model_file(path)


def test_the_torch_filters_loss_equals_the_core_passs(short):
    """Model (b)'s Kalman-informed loss on the windows (torch filter, per-sample q
    from the net's schedule) equals the mean squared velocity error the core's pass
    has at the same truth rows, interpolated the same way."""
    from pronet.experiments.qlearn.gradient import (
        RecordedTraining,
        _schedule,
        _truth_index,
        _window_loss,
        core_plan,
        net_q,
    )
    from pronet.learn.models import DetrendNet
    from pronet.learn.torchfilter.windows import windows
    from pronet.recorded.passes import section_recorded

    torch.manual_seed(0)
    net = DetrendNet(scaling="spread").double()
    scheds = [_schedule(ts) for ts in short[:2]]
    passes = [section_recorded(ts.section, ts.config) for ts in short[:2]]
    with torch.no_grad():
        plans = [
            core_plan(ts, p, sc, net_q(net, sc.windows).numpy())
            for ts, p, sc in zip(short[:2], passes, scheds, strict=True)
        ]
    win = windows(passes, plans, short[0].q_nominal, 2.0)
    ends = [int(np.flatnonzero(win.section == k)[e]) for k in (0, 1) for e in (0, -1)]
    pick = np.array(ends)  # each section's first window (its pass's start) and last
    loss = _window_loss(net, short[:2], scheds, passes, win, pick, RecordedTraining())
    assert {int(s) for s in win.section} == {0, 1}
    err2, rows, length = 0.0, 0, 200  # 2 s windows at 100 Hz
    for w in pick:
        s, first = int(win.section[w]), int(win.first[w])
        core = win.core[s]
        times = core.time[first : first + length + 1]
        i, wt, v, _ = _truth_index(short[s], times)
        vel = core.vel[first : first + length + 1]
        est = (1 - wt)[:, None] * vel[i] + wt[:, None] * vel[i + 1]
        err2 += float(np.sum((est - v) ** 2))
        rows += len(i)
    assert rows > 0
    assert float(loss.detach()) == pytest.approx(err2 / rows, rel=1e-9)
    loss.backward()
    grads = [p.grad for p in net.parameters() if p.grad is not None]
    assert grads and all(torch.isfinite(g).all() for g in grads)
    assert any(float(g.abs().max()) > 0 for g in grads)  # q reaches the loss


def test_a_tiny_cnn_trains_and_runs_from_its_model_file(short, tmp_path):
    from pronet.experiments.qlearn.gradient import RecordedTraining, net_q, train_cnn
    from pronet.learn.hybrid import q_schedule
    from pronet.learn.models import save_net

    hp = RecordedTraining(epochs=2, seconds=2.0, max_windows=2, steps=1)
    net, record = train_cnn(short[:1], hp)
    assert len(record["loss"]) == 2 and np.isfinite(record["loss"]).all()
    save_net(net, tmp_path / "cnn", {"training": record})
    frozen = load_model_file(tmp_path / "cnn")  # the core's forward pass, no torch
    imu = short[1].section.imu
    sched = q_schedule(frozen, imu, short[1].section.imu_time, prior_q=short[1].q_nominal)
    windows = np.lib.stride_tricks.sliding_window_view(imu, 200, 0)[:5]
    with torch.no_grad():
        direct = net_q(net.double(), torch.as_tensor(np.ascontiguousarray(windows))).numpy()
    assert sched.q.shape[1] == 6
    assert np.allclose(frozen.predict(windows.astype(np.float32)), direct, rtol=1e-4)


def test_cli_errors_name_the_option(tmp_path, capsys):
    assert cli.main(["train", "--model", "cnn", "--out", str(tmp_path / "m")]) == 2
    assert "--model cnn: needs --recorded DIR or --simulated N" in capsys.readouterr().err
    assert cli.main(["train", "--recorded", str(tmp_path / "none")]) == 2
    assert "--recorded:" in capsys.readouterr().err
    assert cli.main(["train", "--simulated", "1"]) == 2
    assert "--simulated: needs at least 2" in capsys.readouterr().err
    for argv, name in ((["--simulated", "2", "--data-seed", "-1"], "--data-seed"),
                       (["--simulated", "2", "--seed", "-2"], "--seed"),
                       (["--data-seed", "-3"], "--data-seed")):  # fmt: skip
        assert cli.main(["train", *argv, "--out", str(tmp_path / "m")]) == 2
        assert f"{name}: must be >= 0, got -" in capsys.readouterr().err
    with pytest.raises(ValueError, match="seed: must be >= 0"):
        simulated_sections(2, seed=-1)
    # too many recordings for memory: refused before any is built or anything written
    assert cli.main(["train", "--simulated", "100000", "--out", str(tmp_path / "m")]) == 2
    assert "--simulated: 100000 simulated recordings of 330 s would hold 1" in (
        capsys.readouterr().err
    )
    assert not (tmp_path / "m").exists()
    with pytest.raises(ValueError, match="n: 3000 simulated recordings"):
        simulated_sections(3000)
    for duration in (math.nan, math.inf, 1.0):  # named, before the memory estimate
        with pytest.raises(ValueError, match=r"^duration: must be within \[2, 330\] s"):
            simulated_sections(2, duration=duration)


def test_the_memory_limit_counts_what_a_simulated_recording_holds():
    simulated_sections(1, duration=10.0)  # the trajectory and imports cached first
    tracemalloc.start()
    try:
        held = simulated_sections(2, duration=60.0)
        per_sample = tracemalloc.get_traced_memory()[0] / 2 / 6000
    finally:
        tracemalloc.stop()
    assert len(held) == 2
    assert 0.8 * SIM_BYTES_PER_SAMPLE <= per_sample <= SIM_BYTES_PER_SAMPLE


@pytest.mark.slow
def test_cli_trains_model_a_on_simulated_recordings(tmp_path, capsys):
    out = tmp_path / "scale"
    assert cli.main(["train", "--simulated", "2", "--model", "a", "--out", str(out), "--json"]) == 0
    card = json.loads((tmp_path / "scale.json").read_text())
    assert card["kind"] == "section-scale"
    assert card["training"]["sections"] == ["regimes-0", "regimes-1"]
    assert cli.main(["train", "--simulated", "2", "--model", "a", "--out", str(out)]) == 2
    assert "exists; use --force" in capsys.readouterr().err
    # --data-seed draws the recordings, --seed the training alone.
    argv = ["train", "--simulated", "2", "--model", "a", "--json", "--seed", "1"]
    assert cli.main([*argv, "--data-seed", "5", "--out", str(tmp_path / "five")]) == 0
    card = json.loads((tmp_path / "five.json").read_text())
    assert card["training"]["sections"] == ["regimes-5", "regimes-6"]


@pytest.mark.slow
@pytest.mark.skipif(not SNAPIR.is_dir(), reason="the Snapir data is not on this machine")
def test_snapir_sections_train_and_score():
    sections = recorded_sections(SNAPIR, names=["trajectory02", "trajectory03"])
    assert [s.name for s in sections] == ["trajectory02", "trajectory03"]
    assert sections[0].oracle_q is None
    grid = scale_grid(sections[0], np.array([-1.0, 0.0]))
    assert grid.at((1.0, 1.0))[0] == pytest.approx(constant_metrics(sections[0]).srmse)


def test_pronet_real_runs_a_model_file_as_a_row(tmp_path):
    """``pronet real --model PATH``: the model file's row runs beside the others and
    its card is recorded (its q: the test above)."""
    from pronet.recorded.recordings import write_recording

    from synthetic_recording import DVL_LEVER_ARM, IMU_LEVER_ARM, synthetic_recording

    folder = write_recording(tmp_path / "sec", synthetic_recording(seed=0, duration=30.0).recording)
    model = tmp_path / "scale"
    SectionScale((4.0, 0.25)).save(model, {})
    arms = [f"--imu-lever-arm={','.join(map(str, IMU_LEVER_ARM))}",
            f"--dvl-lever-arm={','.join(map(str, DVL_LEVER_ARM))}"]  # fmt: skip
    argv = ["real", "--data", str(folder), "--format", "generic", "--no-models", "--no-plots"]
    out = tmp_path / "out"
    assert cli.main([*argv, *arms, "--model", str(model), "--out", str(out), "--quiet"]) == 0
    rows = json.loads((out / "metrics.json").read_text())
    text = json.dumps(rows)
    assert f"learned:{model}" in text
    config = json.loads((out / "config.json").read_text())
    assert f"learned:{model}" in json.dumps(config)


def test_an_interrupted_scoring_releases_its_claim_and_a_stale_one_is_recognised(short, tmp_path):
    """A Ctrl-C during ``--cross-validate`` left its claim, and the rerun was refused as
    "already scored" although nothing had been scored. Now a claim is released when the
    scoring stops (nothing was shown), a claim whose process no longer runs (killed) is
    recognised as stale, one whose process runs is refused as in progress, and only a
    pair whose scores came out is refused as scored."""
    ledger = Ledger(tmp_path / "ledger.jsonl")

    def interrupted(train, grids):
        raise KeyboardInterrupt

    def unit(train, grids):
        return SectionScale((1.0, 1.0))

    with pytest.raises(KeyboardInterrupt):
        cross_validate(short[:2], {"probe": (interrupted, scale_scorer)}, ledger=ledger)
    ev = cross_validate(short[:2], {"probe": (unit, scale_scorer)}, ledger=ledger)
    assert sorted(ev.rows["probe"]) == sorted(t.name for t in short[:2])
    with pytest.raises(ValueError, match="'probe' was already scored on 'LOSO "):
        cross_validate(short[:2], {"probe": (unit, scale_scorer)}, ledger=ledger)
    # a claim left by a process killed while scoring: stale, taken over
    gone = subprocess.Popen([sys.executable, "-c", "pass"])
    gone.wait()
    host = socket.gethostname()
    claim = {"model": "m", "test_set": "held-out x", "state": "claimed", "host": host}
    other = Ledger(tmp_path / "other.jsonl")
    other.path.write_text(json.dumps({**claim, "pid": gone.pid, "time": "then"}) + "\n")
    with other.scoring([("m", "held-out x")]):
        pass
    assert f"stale claim of process {gone.pid}" in other.entries()[-2]["note"]
    with pytest.raises(ValueError, match="already scored"):
        other.claim("m", "held-out x")
    # a claim whose process still runs: in progress, refused
    other.path.write_text(json.dumps({**claim, "pid": os.getppid(), "time": "now"}) + "\n")
    with pytest.raises(
        ValueError, match=rf"'m' is being scored on 'held-out x' by process {os.getppid()}"
    ):
        other.claim("m", "held-out x")
