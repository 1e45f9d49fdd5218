"""The safety probe's benchmark: its figures come from the simulated arm through the layer."""

import json

import pytest
from typer.testing import CliRunner

from wovenskin.bench.safety import run_safety_benchmark
from wovenskin.cli import app


@pytest.mark.slow
def test_probe_reports_clearance_and_caps_that_hold() -> None:
    result = run_safety_benchmark(episodes=2, seed=3)
    assert set(result.joint_6_clearance_deg) == {"30", "60", "100", "148"}
    # the margin holds at every speed (the stopping distance is in the look-ahead)
    assert min(result.joint_6_clearance_deg.values()) >= result.joint_margin_deg
    assert 0.5 < result.caps.linear <= 1.0
    assert 0.0 < result.caps.angular <= 1.0
    assert result.caps.outside_mm <= 0.0
    assert result.caps.into_margin_deg <= 0.0


def test_bad_episode_count_is_refused() -> None:
    with pytest.raises(ValueError, match="episodes must be at least 1"):
        run_safety_benchmark(episodes=0)


def test_cli_prints_json() -> None:
    out = CliRunner().invoke(app, ["bench", "safety", "--episodes", "1", "--json"])
    assert out.exit_code == 0, out.output
    figures = json.loads(out.stdout)
    assert figures["episodes"] == 1 and figures["caps"]["linear"] <= 1.0
