"""Plans stepped in session time: sleeps, waits on sights, time-outs, give-ups."""

import pytest

from wovenskin.operators.script import ScriptRunner, Sleep, Timeout, Until, run_blocking


def _run(runner: ScriptRunner, until: float, dt: float = 0.005) -> float:
    t = 0.0
    while runner.running and t < until:
        t += dt
        runner.tick(t)
    return t


def test_sleeps_take_session_time():
    log = []

    def plan():
        yield Sleep(0.5)
        log.append("a")
        yield Sleep(1.0)
        log.append("b")
        return 7

    runner = ScriptRunner()
    runner.start(plan(), 0.0)
    end = _run(runner, 5.0)
    assert log == ["a", "b"] and runner.result == 7
    assert 1.5 <= end <= 1.53


def test_until_resumes_when_seen_and_times_out_into_the_plan():
    seen = {"t": 0.0}
    out = []

    def plan():
        yield Until(lambda: seen["t"] >= 0.3, 10.0, "the sight")
        out.append("seen")
        try:
            yield Until(lambda: False, 0.2, "never")
        except Timeout as exc:
            out.append(str(exc))

    runner = ScriptRunner()
    runner.start(plan(), 0.0)
    t = 0.0
    while runner.running and t < 2.0:
        t += 0.01
        seen["t"] = t
        runner.tick(t)
    assert out[0] == "seen" and "never not seen in 0.2 s" in out[1]


def test_an_error_stops_the_plan_and_is_kept():
    def plan():
        yield Sleep(0.1)
        raise ValueError("cannot go on")

    runner = ScriptRunner()
    runner.start(plan(), 0.0)
    _run(runner, 1.0)
    assert not runner.running and isinstance(runner.error, ValueError)


def test_starting_a_new_plan_closes_the_old_one():
    closed = []

    def plan():
        try:
            yield Sleep(10.0)
        finally:
            closed.append(True)

    runner = ScriptRunner()
    runner.start(plan(), 0.0)
    runner.tick(0.01)
    runner.start(plan(), 0.02)
    assert closed == [True]


class _Clock:
    """A session clock that moves on 0.1 s every time it is read."""

    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        self.t += 0.1
        return self.t


def test_run_blocking_waits_on_the_session_clock_and_returns_the_result():
    clock, woke = _Clock(), []

    def plan():
        yield Sleep(1.0)
        woke.append(clock.t)
        yield Until(lambda: clock.t > 2.0, 10.0, "later")
        return "done"

    assert run_blocking(plan(), clock, poll_s=0.0) == "done"
    assert woke[0] >= 1.0 and clock.t > 2.0


def test_run_blocking_raises_the_plans_error():
    def failing():
        yield Sleep(0.2)
        raise ValueError("cannot go on")

    with pytest.raises(ValueError, match="cannot go on"):
        run_blocking(failing(), _Clock(), poll_s=0.0)
