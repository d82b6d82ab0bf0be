"""Model (c), the A-KIT-like Q model that reads the filter's velocity: its chunked
torch-filter loss equals the core's pass, its training step moves it, and its
schedule on recorded sensors is causal (each instant's q from the core's velocity at
that epoch) and runs by learned:PATH in the run path."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from pronet.experiments.qlearn.akit_training import (
    _chunked_loss,
    _core_velocity_plan,
    train_akit,
)
from pronet.experiments.qlearn.gradient import RecordedTraining, _schedule, _truth_index
from pronet.experiments.qlearn.scoring import run_pass
from pronet.experiments.qlearn.sections import simulated_sections
from pronet.learn.akit import AkitNet, akit_schedule, save_akit
from pronet.learn.qmodels import load_model_file
from pronet.learn.torchfilter.windows import windows
from pronet.recorded.passes import section_recorded
from pronet.run import run
from pronet.strategies import StrategySpec, strategy


@pytest.fixture(scope="module")
def short() -> list:
    return simulated_sections(2, seed=11, duration=20.0)


def test_the_chunked_loss_equals_the_core_pass_at_the_truth_rows(short):
    torch.manual_seed(1)
    net = AkitNet().double()
    with torch.no_grad():  # a velocity-dependent net: the last layer no longer zero
        net.mlp[-1].weight.normal_(0.0, 0.3)
    ts = short[0]
    rec = section_recorded(ts.section, ts.config)
    sc = _schedule(ts)
    plan = (np.array([rec.t0]), np.array([ts.q_nominal]))
    for _ in range(3):  # the fixed point of the closed loop on the core
        plan = _core_velocity_plan(net, ts, rec, sc, plan)
    win = windows([rec], [plan], ts.q_nominal, 3.0)
    pick = np.arange(len(win.section))
    loss = _chunked_loss(net, [ts], [sc], [rec], [plan], win, pick, RecordedTraining())
    # the core with the torch run's own q: the same errors at the same rows
    core = win.core[0]
    err2, rows = 0.0, 0
    for w in pick:
        first = int(win.first[w])
        times = core.time[first : first + 301]
        i, wt, v, _ = _truth_index(ts, times)
        vel = core.vel[first : first + 301]
        err2 += float(np.sum(((1 - wt)[:, None] * vel[i] + wt[:, None] * vel[i + 1] - v) ** 2))
        rows += len(i)
    # the plan is the closed loop's fixed point only approximately: within 1e-6
    assert float(loss.detach()) == pytest.approx(err2 / rows, rel=1e-6)
    loss.backward()
    assert float(net.mlp[0].weight.grad.abs().max()) > 0  # through q and the velocity


def test_a_trained_akit_runs_causally_from_its_model_file(short, tmp_path):
    hp = RecordedTraining(epochs=1, seconds=2.0, max_windows=2, steps=1)
    net, record = train_akit(short[:1], hp)
    assert np.isfinite(record["loss"]).all()
    save_akit(net, tmp_path / "akit", {"training": record})
    loaded = load_model_file(tmp_path / "akit")
    assert isinstance(loaded, AkitNet)
    ts = short[1]
    rec = section_recorded(ts.section, ts.config)
    sched = akit_schedule(loaded, rec, ts.q_nominal)
    assert sched.q.shape == (len(sched.time), 6) and len(sched.time) > 10
    # causal: the full pass with the schedule has, at each instant, the velocity the
    # stepped run handed the net there
    full = run_pass(ts, sched.time, sched.q)
    ends = np.searchsorted(rec.imu_time, sched.time) + 1
    win = np.lib.stride_tricks.sliding_window_view(rec.imu, 200, 0)[ends - 200]
    with torch.no_grad():
        again = loaded(torch.as_tensor(np.ascontiguousarray(win)), torch.as_tensor(full.vel[ends]))
    assert np.allclose(again.numpy(), sched.q, rtol=1e-9)
    # learned:PATH in the run path takes that schedule
    row = strategy(StrategySpec.parse(f"learned:{tmp_path / 'akit'}"), ts.q_nominal)
    done = run(row, rec)
    assert np.allclose(done.schedule.q, sched.q)
    assert np.allclose(done.result.vel, full.vel)
