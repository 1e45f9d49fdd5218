"""The dashboard without a browser: scene geometry, page state, runner commands, server."""

from __future__ import annotations

import json
import time

import numpy as np
import pytest
from fastapi.testclient import TestClient
from stand_ins import ContactMeans
from stand_ins import wait_until as _wait
from starlette.websockets import WebSocketDisconnect

from wovenskin.gestures import CLASS_NAMES
from wovenskin.recognition.pipeline import PipelineSettings
from wovenskin.recording.formats import write_labelled_stream
from wovenskin.robots.sim import SimRobot
from wovenskin.robots.sim.tm5_900 import INITIAL_Q
from wovenskin.robots.techman import FakeListenNode, TechmanRobot
from wovenskin.robots.ur import URRobot
from wovenskin.robots.ur.models import ur_model
from wovenskin.runtime.session import open_session
from wovenskin.sim.live_touches import Fingertip
from wovenskin.sim.pty_skin import FakeSkinDevice
from wovenskin.sim.stream import simulate_stream
from wovenskin.skin.layout import SkinLayout
from wovenskin.ui.dashboard import server
from wovenskin.ui.dashboard.page_touch import parse_touch_message, parse_touches
from wovenskin.ui.dashboard.runner import DashboardRunner
from wovenskin.ui.dashboard.scene import ArmScene
from wovenskin.ui.dashboard.server import create_app, loopback_host, needs_token


class LocalClient(TestClient):
    """A test client that, like a browser on this machine, names the server 127.0.0.1.

    Without a token the server answers only loopback names (a DNS-rebinding guard), and the
    test client's own default host, ``testserver``, is none."""

    def __init__(self, app, **kwargs) -> None:
        super().__init__(app, base_url="http://127.0.0.1", **kwargs)

    def websocket_connect(self, url: str, *args, **kwargs):
        return super().websocket_connect(f"ws://127.0.0.1{url}", *args, **kwargs)


def local_client(app) -> TestClient:
    """A :class:`LocalClient` of ``app``."""
    return LocalClient(app)


# -- scene ------------------------------------------------------------------------------


def test_the_scene_matches_the_simulated_arm() -> None:
    robot = SimRobot()
    scene = ArmScene.for_robot(robot)
    assert scene is not None
    names = [shape.name for shape in scene.shapes]
    assert "skin_patch" in names and "floor" not in names
    poses = scene.poses(INITIAL_Q)
    assert len(poses) == len(scene.shapes) and all(len(p) == 7 for p in poses)
    robot.connect()
    tcp = robot.state().tcp.position
    fingers = [p[:3] for p, s in zip(poses, scene.shapes, strict=True) if "finger" in s.name]
    assert np.linalg.norm(np.mean(fingers, axis=0) - tcp) < 0.06  # the fingertips hold the TCP
    with pytest.raises(ValueError, match="joint angles"):
        scene.poses([0.0] * 5)
    with pytest.raises(ValueError, match="joint angles"):
        scene.poses([np.nan] * 6)


def test_the_skin_corners_span_the_layout_with_up_along_the_patch() -> None:
    scene = ArmScene.for_robot(SimRobot())
    scene.poses(INITIAL_Q)
    layout = SkinLayout()
    top_left, top_right, bottom_left = (np.asarray(c) for c in scene.skin_corners(layout))
    assert np.linalg.norm(top_right - top_left) == pytest.approx(layout.width_mm / 1000, abs=1e-4)
    assert np.linalg.norm(bottom_left - top_left) == pytest.approx(
        layout.height_mm / 1000, abs=1e-4
    )
    assert abs(np.dot(top_right - top_left, bottom_left - top_left)) < 1e-8  # a rectangle


def test_arms_without_a_model_get_no_scene() -> None:
    class Other:
        pass

    assert ArmScene.for_robot(Other()) is None


# -- runner -----------------------------------------------------------------------------


def _opener(tmp_path, gesture: str = "swipe_up"):
    def opener(skin: str, robot: str):
        return open_session(
            skin, robot, recognizer=ContactMeans(gesture), poses=tmp_path / "poses.toml"
        )

    return opener


@pytest.fixture()
def runner(tmp_path):
    runner = DashboardRunner(
        _opener(tmp_path), "sim:auto=0,seed=2", "sim", record_dir=tmp_path / "rec"
    )
    runner.start()
    assert _wait(lambda: runner.latest() is not None and not runner.latest()["skin"]["calibrating"])
    yield runner
    runner.close()


def test_the_page_state_is_complete_and_json(runner) -> None:
    state = runner.latest()
    text = json.dumps(state, allow_nan=False)  # what the server sends
    assert len(text) < 20_000
    skin = state["skin"]
    assert len(skin["signal"]) == skin["rows"] * skin["cols"] == 100 and skin["virtual"]
    assert state["recognition"]["classes"] == list(CLASS_NAMES)
    assert len(state["robot"]["geoms"]) == len(runner.scene.shapes)
    assert len(state["robot"]["skin_corners"]) == 3 and len(state["robot"]["twist"]) == 6
    assert "lookahead=0.03" in state["skin"]["source"]  # quick virtual touches
    assert state["sim_slowed_s"] >= 0.0  # how far a busy machine slowed the simulated world
    described = runner.describe()
    assert described["gestures"] == [n for n in CLASS_NAMES if n != "invalid"]
    limits = runner.session.safety.limits  # the box the 3D view draws is the enforced one
    assert described["workspace"]["lower"] == pytest.approx(limits.workspace_lower.tolist())
    assert described["workspace"]["upper"] == pytest.approx(limits.workspace_upper.tolist())


def test_page_states_come_at_the_page_rate_while_control_runs_at_the_skin_rate(runner) -> None:
    first = runner.latest()["seq"]
    time.sleep(1.0)
    state = runner.latest()
    assert state["seq"] - first > 10  # a stream of states (the rate itself is benchmarked)
    assert state["rates"]["control_hz"] > 3 * state["rates"]["ui_hz"] > 0


def test_virtual_touches_reach_the_robot_only_through_the_recogniser(runner) -> None:
    runner.touch({1: Fingertip(50.0, 70.0, 1.5)})
    assert _wait(lambda: runner.latest()["recognition"]["command"] == "swipe_up")
    assert _wait(lambda: runner.latest()["robot"]["tcp_speed"] > 0.01)
    assert runner.latest()["latency"]["command"] == "swipe_up"
    runner.touch({})
    assert _wait(lambda: runner.latest()["recognition"]["command"] is None)
    timeline = runner.latest()["timeline"]
    assert [e["name"] for e in timeline if e["kind"] == "command"][-2:] == ["swipe_up", None]


def test_a_touch_shows_the_recognisers_tracks_where_the_fingers_are(tmp_path) -> None:
    def opener(skin: str, robot: str):
        return open_session(
            skin, robot, recognizer=ContactMeans("swipe_up"), poses=tmp_path / "poses.toml",
            pipeline_settings=PipelineSettings(reader="touch"),
        )  # fmt: skip

    runner = DashboardRunner(opener, "sim:auto=0,seed=2", "sim", record_dir=tmp_path / "rec")
    runner.start()
    try:
        assert _wait(lambda: runner.latest() and not runner.latest()["skin"]["calibrating"])
        assert runner.latest()["skin"]["tracks"] == []
        # x right, y down from the corner (mm): columns 2.5 and 6.5, row 4.5 of the 10 x 10 skin
        runner.touch({1: Fingertip(30.0, 70.0, 1.5), 2: Fingertip(70.0, 70.0, 1.5)})
        assert _wait(lambda: len(runner.latest()["skin"]["tracks"]) == 2)
        skin = runner.latest()["skin"]
        tracks = sorted(skin["tracks"], key=lambda t: t["col"])
        assert len({t["id"] for t in tracks}) == 2 and min(t["id"] for t in tracks) >= 1
        for track, col in zip(tracks, (2.5, 6.5), strict=True):
            assert -0.5 <= track["row"] <= skin["rows"] - 0.5
            assert -0.5 <= track["col"] <= skin["cols"] - 0.5
            assert track["row"] == pytest.approx(4.5, abs=1.0)  # the contacts' coordinates
            assert track["col"] == pytest.approx(col, abs=1.0)
            assert {"v_row", "v_col", "speed_mm_s", "travel_mm", "merged"} <= set(track)
        json.dumps(skin, allow_nan=False)
        runner.touch({})
        assert _wait(lambda: runner.latest()["skin"]["tracks"] == [])
    finally:
        runner.close()


def test_commands_stop_resume_speed_and_record(runner, tmp_path) -> None:
    runner.submit({"cmd": "stop"})
    assert _wait(lambda: runner.latest()["safety"]["user_stopped"])
    runner.touch({1: Fingertip(50.0, 70.0, 1.5)})
    time.sleep(0.5)
    assert runner.latest()["robot"]["tcp_speed"] == 0.0  # stopped: a touch does not move it
    runner.touch({})
    runner.submit({"cmd": "resume"})
    runner.submit({"cmd": "speed", "value": 0.5})
    runner.submit({"cmd": "record", "on": True})
    assert _wait(lambda: runner.latest()["recording"] is not None)
    assert runner.latest()["speed_scale"] == 0.5 and not runner.latest()["safety"]["stopped"]
    runner.submit({"cmd": "record", "on": False})
    assert _wait(lambda: runner.latest()["recording"] is None)
    assert len(list((tmp_path / "rec").glob("dashboard-*.wsrec"))) == 1


def test_bad_commands_are_one_line_messages_and_change_nothing(runner) -> None:
    with pytest.raises(ValueError, match="unknown dashboard command"):
        runner.submit({"cmd": "launch"})
    runner.submit({"cmd": "speed", "value": 7})
    runner.submit({"cmd": "perform", "gesture": "wave"})
    runner.submit({"cmd": "switch", "robot": "abb:1.2.3.4"})
    assert _wait(lambda: sum("error" in m for m in runner.latest()["messages"]) >= 3)
    state = runner.latest()
    assert state["speed_scale"] == 1.0 and state["robot"]["spec"] == "sim"
    assert runner.running


def test_switching_the_robot_reopens_the_session(runner) -> None:
    old = runner.session
    runner.submit({"cmd": "switch", "robot": "sim", "skin": "sim:auto=0,seed=9"})
    assert _wait(lambda: runner.session is not old and runner.latest()["skin"]["source"].startswith(
        "sim:auto=0,seed=9"))  # fmt: skip


def test_the_virtual_skin_needs_the_simulated_skin(tmp_path) -> None:
    path = tmp_path / "s.npz"
    write_labelled_stream(path, simulate_stream(3.0, seed=1))
    runner = DashboardRunner(_opener(tmp_path), f"replay:{path}", "sim")
    runner.start()
    try:
        with pytest.raises(ValueError, match="simulated skin"):
            runner.touch({1: Fingertip(1.0, 1.0, 1.0)})
        assert _wait(lambda: runner.latest() is not None)
        assert runner.latest()["skin"]["virtual"] is False
    finally:
        runner.close()


# -- server -----------------------------------------------------------------------------


def test_parse_touches_accepts_only_well_formed_touches() -> None:
    touches = parse_touches([{"id": 3, "x_mm": 1, "y_mm": 2.5, "force_n": 0.5}])
    assert touches == {3: Fingertip(1.0, 2.5, 0.5)}
    for bad in ({}, [1], [{"id": 1}], [{"id": 1, "x_mm": "nan", "y_mm": 0, "force_n": 1}]):
        with pytest.raises(ValueError):
            parse_touches(bad)


def test_touch_messages_carry_one_or_several_timed_samples() -> None:
    tip = {"id": 1, "x_mm": 5, "y_mm": 6, "force_n": 1}
    assert parse_touch_message({"touches": [tip]}) == [(None, {1: Fingertip(5.0, 6.0, 1.0)})]
    message = {"samples": [{"t": 1.5, "touches": [tip]}, {"t": 1.6, "touches": []}]}
    samples = parse_touch_message(message)
    assert [t for t, _ in samples] == [1.5, 1.6] and samples[1][1] == {}
    for bad in ({"samples": []}, {"samples": "x"}, {"samples": [{"t": "soon", "touches": []}]},
                {"samples": [{"touches": [tip]}] * 65}):  # fmt: skip
        with pytest.raises(ValueError):
            parse_touch_message(bad)


def test_other_devices_get_the_machines_network_addresses(monkeypatch) -> None:
    monkeypatch.setattr(server, "lan_addresses", lambda: ["192.168.1.23", "10.0.0.7"])
    url = "http://127.0.0.1:8000/?token=abc"
    assert server.other_device_urls(url, "0.0.0.0") == [
        "http://192.168.1.23:8000/?token=abc",
        "http://10.0.0.7:8000/?token=abc",
    ]
    assert server.other_device_urls(url, "127.0.0.1") == []  # nobody else can reach it
    monkeypatch.undo()
    addresses = server.lan_addresses()  # the real ones: whatever this machine has
    assert all(not a.startswith("127.") and a.count(".") == 3 for a in addresses)


def test_only_loopback_addresses_go_without_a_token() -> None:
    assert not needs_token("127.0.0.1") and not needs_token("localhost")
    assert needs_token("0.0.0.0") and needs_token("192.168.1.20")


def test_the_socket_sends_the_scene_then_states_and_takes_commands(runner) -> None:
    client = local_client(create_app(runner))
    assert "wovenskin" in client.get("/").text
    assert client.get("/static/vendor/three.min.js").status_code == 200
    with client.websocket_connect("/ws") as ws:
        assert ws.receive_json()["type"] == "scene"
        assert ws.receive_json()["type"] == "state"
        touch = {"id": 1, "x_mm": 50, "y_mm": 70, "force_n": 1.5}
        ws.send_text(json.dumps({"type": "touch", "touches": [touch]}))
        assert _wait(lambda: runner.latest()["recognition"]["command"] == "swipe_up")
        ws.send_text("not json")
        ws.send_text(json.dumps({"type": "touch", "touches": "everywhere"}))
        ws.send_text(json.dumps({"type": "command", "cmd": "stop"}))
        errors = []
        while len(errors) < 2:
            message = ws.receive_json()
            if message["type"] == "error":
                errors.append(message["message"])
        assert _wait(lambda: runner.latest()["safety"]["user_stopped"])


FINGER = {"id": 1, "x_mm": 50, "y_mm": 70, "force_n": 1.5}  # a page's fingertip, as sent


def _put_a_finger_down(ws, runner) -> None:
    """A freshly opened page puts one finger down; the stand-in makes that ``swipe_up``."""
    assert ws.receive_json()["type"] == "scene"
    ws.send_text(json.dumps({"type": "touch", "touches": [FINGER]}))
    assert _wait(lambda: runner.latest()["recognition"]["command"] == "swipe_up")


def test_a_page_that_goes_away_with_a_finger_down_lifts_it(runner) -> None:
    client = local_client(create_app(runner))
    with client.websocket_connect("/ws") as ws:
        _put_a_finger_down(ws, runner)
    # the socket closed with the finger down: the finger lifts, the command ends
    assert _wait(lambda: runner.latest()["recognition"]["command"] is None)
    assert _wait(lambda: runner.latest()["robot"]["tcp_speed"] < 1e-3)


def test_a_page_that_stops_talking_with_a_finger_down_has_it_lifted(runner) -> None:
    client = local_client(create_app(runner))
    with client.websocket_connect("/ws") as ws:
        _put_a_finger_down(ws, runner)
        started = time.monotonic()
        for _ in range(13):  # heartbeats (every 0.1 s here: margin for a busy machine)
            time.sleep(0.1)
            ws.send_text(json.dumps({"type": "touch", "touches": [FINGER]}))
        assert runner.latest()["recognition"]["command"] == "swipe_up"
        assert time.monotonic() - started > 1.2  # longer than the silence allowed
        # then silence, the socket still open: the finger lifts, the command ends
        assert _wait(lambda: runner.latest()["recognition"]["command"] is None, 15.0)
        assert _wait(lambda: any("stopped sending" in m for m in runner.latest()["messages"]))


def test_one_page_draws_at_a_time(runner) -> None:
    client = local_client(create_app(runner))
    with client.websocket_connect("/ws") as first, client.websocket_connect("/ws") as second:
        assert second.receive_json()["type"] == "scene"
        _put_a_finger_down(first, runner)
        second.send_text(json.dumps({"type": "touch", "touches": []}))  # would lift the first's
        while (reply := second.receive_json())["type"] != "error":
            pass
        assert "another page" in reply["message"]
        time.sleep(0.2)
        assert runner.latest()["recognition"]["command"] == "swipe_up"  # still held
        first.send_text(json.dumps({"type": "touch", "touches": []}))
        assert _wait(lambda: runner.latest()["recognition"]["command"] is None)
        second.send_text(json.dumps({"type": "touch", "touches": [FINGER]}))  # now it may
        assert _wait(lambda: runner.latest()["recognition"]["command"] == "swipe_up")
        second.send_text(json.dumps({"type": "touch", "touches": []}))


def test_a_token_guards_every_request_and_the_socket(runner) -> None:
    client = TestClient(create_app(runner, token="s3cret"))
    assert client.get("/").status_code == 401
    assert client.get("/api/state").status_code == 401
    assert client.get("/?token=wrong").status_code == 401
    assert client.get("/?token=s3cret").status_code == 200
    assert client.get("/api/state").status_code == 200  # the cookie set by the first visit
    fresh = TestClient(create_app(runner, token="s3cret"))
    with pytest.raises(WebSocketDisconnect), fresh.websocket_connect("/ws") as ws:
        ws.receive_json()
    with fresh.websocket_connect("/ws?token=s3cret") as ws:
        assert ws.receive_json()["type"] == "scene"


def test_a_serial_skin_drives_the_page_and_a_pulled_cable_stops_the_arm(tmp_path) -> None:
    device = FakeSkinDevice().start()
    runner = DashboardRunner(_opener(tmp_path), f"serial:{device.port}", "sim")
    try:
        runner.start()
        assert _wait(lambda: runner.latest() is not None and runner.latest()["skin"]["fps"] > 50)
        state = runner.latest()
        assert state["skin"]["virtual"] is False and state["autoplay"] is None
        assert state["skin"]["counters"]["good"] > 0
        runner.submit({"cmd": "perform", "gesture": "push"})
        assert _wait(
            lambda: any("only the simulated skin" in m for m in runner.latest()["messages"])
        )
        device.stop()  # the cable is pulled
        assert _wait(lambda: runner.latest()["safety"]["stopped"], timeout=15.0)
        assert runner.running
    finally:
        runner.close()
        device.stop()


def test_a_techman_arm_is_drawn_with_the_tm5_900_model() -> None:
    scene = ArmScene.for_robot(TechmanRobot("127.0.0.1"))  # built, never connected
    assert scene is not None and len(scene.poses(INITIAL_Q)) == len(scene.shapes)


@pytest.mark.parametrize("model", [None, "ur10e"])
def test_a_ur_arm_is_drawn_from_its_own_dh_table(model) -> None:
    scene = ArmScene.for_robot(URRobot("10.0.0.5", model=model))  # built, never connected
    assert scene is not None
    q = np.array([0.1, -1.2, 1.3, -1.6, -1.57, 0.3])  # as getActualQ reports them
    poses = dict(zip([s.name for s in scene.shapes], scene.poses(q), strict=True))
    flange = ur_model(model or "ur5e").flange_pose(q)
    end_link = np.asarray(poses["end_link"][:3])
    assert np.linalg.norm(end_link - (flange[:3, 3] - 0.05 * flange[:3, 2])) < 1e-4
    top_left, top_right, _ = (np.asarray(c) for c in scene.skin_corners(SkinLayout()))
    columns = (top_right - top_left) / np.linalg.norm(top_right - top_left)
    assert columns @ flange[:3, 2] == pytest.approx(1.0, abs=1e-6)  # columns run to the tool


def test_the_page_draws_a_ur_arm_at_the_joints_it_reports(tmp_path) -> None:
    from ur_stand_ins import FakeControl, FakeReceive

    receive = FakeReceive()

    def opener(skin: str, robot: str):
        arm = URRobot(
            "10.0.0.5", control_factory=lambda h: FakeControl(), receive_factory=lambda h: receive
        )
        # no model named: the safety layer refuses such an arm unless the user opts into
        # degraded safety (ur:HOST?safety=degraded); this test is about the drawing
        arm.degraded_safety = True
        return open_session(
            skin, arm, recognizer=ContactMeans("swipe_up"), poses=tmp_path / "poses.toml"
        )

    runner = DashboardRunner(opener, "sim:auto=0", "ur:10.0.0.5?safety=degraded")
    runner.start()
    try:
        assert _wait(lambda: runner.latest() is not None)
        scene = runner.describe()["scene"]
        state = runner.latest()
        assert len(state["robot"]["geoms"]) == len(scene["geoms"]) > 10
        assert any("draws a UR5e" in line for line in state["messages"])
        receive.q = [0.5, -1.0, 1.0, -1.5, -1.57, 0.0]  # the arm moved: so does its drawing
        before = state["robot"]["geoms"]
        assert _wait(lambda: runner.latest()["robot"]["geoms"] != before)
    finally:
        runner.close()


def test_a_techman_arm_is_driven_from_the_page_through_its_listen_node(tmp_path) -> None:
    with FakeListenNode() as node:

        def opener(skin: str, robot: str):
            arm = TechmanRobot("127.0.0.1", node.listen_port, node.state_port, timeout_s=0.5)
            return open_session(
                skin, arm, recognizer=ContactMeans("swipe_up"), poses=tmp_path / "poses.toml"
            )

        runner = DashboardRunner(opener, "sim:auto=0,seed=4", f"tm:127.0.0.1:{node.listen_port}")
        runner.start()
        try:
            assert _wait(lambda: runner.latest() and not runner.latest()["skin"]["calibrating"])
            state = runner.latest()
            assert len(state["robot"]["geoms"]) == len(runner.describe()["scene"]["geoms"])
            start = np.asarray(state["robot"]["tcp"]["pos"])
            runner.touch({1: Fingertip(50.0, 70.0, 1.5)})  # the page's finger
            assert _wait(lambda: runner.latest()["recognition"]["command"] == "swipe_up")

            def streaming() -> bool:
                return any(
                    line.startswith("SetContinueVLine(") and line != "SetContinueVLine(0,0,0,0,0,0)"
                    for line in node.scripts
                )

            def travel() -> float:
                return float(np.linalg.norm(runner.latest()["robot"]["tcp"]["pos"] - start))

            assert _wait(streaming)  # velocities go to the arm in velocity mode
            assert _wait(lambda: travel() > 0.002)  # and the arm reports that it moved
            runner.touch({})  # lift-off: the command ends, the arm is brought to rest
            assert _wait(lambda: runner.latest()["recognition"]["command"] is None)
            assert _wait(lambda: node.scripts[-1] == "SetContinueVLine(0,0,0,0,0,0)")
            assert _wait(lambda: runner.latest()["robot"]["tcp_speed"] < 1e-3)
        finally:
            runner.close()
        assert not node.velocity_mode  # closing the page's session leaves velocity mode
        assert "StopContinueVmode()" in node.scripts[-4:]
        assert node.violations == []


def test_sockets_from_another_site_are_refused(runner) -> None:
    client = local_client(create_app(runner))
    with (
        pytest.raises(WebSocketDisconnect),
        client.websocket_connect("/ws", headers={"origin": "http://evil.example"}) as ws,
    ):
        ws.receive_json()
    with client.websocket_connect("/ws", headers={"origin": "http://127.0.0.1"}) as ws:
        assert ws.receive_json()["type"] == "scene"


# -- hostile input and careless Apply (issue 13) --------------------------------------


def test_apply_with_an_unknown_skin_spec_keeps_the_running_session(runner) -> None:
    """The spec is checked completely before the session is touched: the arm stays where
    it is, the counters and the timeline go on, the page is told why in one line."""
    runner.touch({1: Fingertip(50.0, 70.0, 1.5)})  # something in the timeline
    assert _wait(lambda: runner.latest()["recognition"]["command"] == "swipe_up")
    assert _wait(lambda: runner.latest()["robot"]["tcp_speed"] > 0.01)  # the arm moves
    runner.touch({})
    assert _wait(lambda: runner.latest()["recognition"]["command"] is None)
    assert _wait(lambda: runner.latest()["robot"]["tcp_speed"] < 1e-4)
    time.sleep(0.3)  # at rest
    old, before = runner.session, runner.latest()
    assert not np.allclose(before["robot"]["q"], INITIAL_Q, atol=1e-3)  # away from home
    for spec in ("bogus:xyz", "replay:/nowhere/missing.npz", "sim:auto=0,gain=lots"):
        runner.submit({"cmd": "switch", "skin": spec, "robot": "sim"})
        assert _wait(lambda s=spec: any(s in m for m in runner.latest()["messages"]))
    after = runner.latest()
    assert runner.session is old and runner.skin_spec == before["skin"]["source"]
    errors = [m for m in after["messages"] if m.startswith("error: switch:")]
    assert len(errors) == 3 and all("kept skin sim:auto=0,seed=2" in m for m in errors)
    assert not any(m.startswith("now: skin") for m in after["messages"])
    assert after["skin"]["counters"]["good"] > before["skin"]["counters"]["good"]  # not reset
    assert np.allclose(after["robot"]["q"], before["robot"]["q"], atol=1e-4)  # no jump home
    names = [e["name"] for e in after["timeline"] if e["kind"] == "command"]
    assert "swipe_up" in names  # the timeline was kept


def test_only_loopback_host_names_reach_a_server_without_a_token(runner) -> None:
    """DNS rebinding: a page from rebind.attacker.example (re-pointed at 127.0.0.1) sends
    its own name as Host and Origin; it gets 403 and its socket is refused, so its
    ``perform swipe_up`` never reaches the arm."""
    app = create_app(runner)
    evil = "rebind.attacker.example:8000"
    client = TestClient(app, base_url=f"http://{evil}")
    page = client.get("/")
    assert page.status_code == 403 and "loopback" in page.text
    assert client.get("/api/state").status_code == 403
    perform = json.dumps({"type": "command", "cmd": "perform", "gesture": "swipe_up"})
    origin = {"origin": f"http://{evil}"}
    with (
        pytest.raises(WebSocketDisconnect) as refused,
        client.websocket_connect(f"ws://{evil}/ws", headers=origin) as ws,
    ):
        ws.send_text(perform)
        ws.receive_json()
    assert refused.value.code == 4403
    time.sleep(0.3)
    assert runner.latest()["robot"]["tcp_speed"] < 1e-3
    assert not any("performs swipe_up" in m for m in runner.latest()["messages"])
    for name in ("localhost:8000", "127.0.0.1", "[::1]:8000", "127.0.0.2:80"):
        assert loopback_host(name), name
        assert TestClient(app, base_url=f"http://{name}").get("/").status_code == 200
    for name in ("", "rebind.attacker.example", "localhost.attacker.example", "0.0.0.0:8000",
                 "192.168.1.20:8000", "[::1"):  # fmt: skip
        assert not loopback_host(name), name
    # an origin that is not the page's own address is refused on a loopback Host, too
    local = LocalClient(app)
    with (
        pytest.raises(WebSocketDisconnect),
        local.websocket_connect("/ws", headers={"origin": f"http://{evil}"}) as ws,
    ):
        ws.receive_json()
    # with a token (a server on the network) other names are fine: the token guards
    tokened = TestClient(create_app(runner, token="s3cret"), base_url="http://192.168.1.20")
    assert tokened.get("/?token=s3cret").status_code == 200


def test_hostile_socket_messages_get_an_error_reply_and_keep_the_connection(runner) -> None:
    client = local_client(create_app(runner))
    touch = '{{"type": "touch", "touches": [{{"id": {}, "x_mm": 5, "y_mm": 5, "force_n": 1}}]}}'
    hostile = [
        touch.format("Infinity"),
        touch.format("1e400"),
        touch.format("-Infinity"),
        touch.format("2.5"),
        '{"type": "touch", "samples": [{"t": 1e400, "touches": []}]}',
        "[" * 3000 + "]" * 3000,
        '{"type": "command", "cmd": "perform", "gesture": ' + "[" * 3000 + "]" * 3000 + "}",
        '{"type": "' + "x" * 100 + '"}',
    ]
    with client.websocket_connect("/ws") as ws:
        assert ws.receive_json()["type"] == "scene"
        for text in hostile:
            ws.send_text(text)
        ws.send_bytes(b"\x00\x01 a binary frame")
        ws.send_text('{"type": "ping", "t": 1e400}')
        ws.send_text('{"type": "ping", "t": 7}')
        errors, pongs = [], []
        while len(pongs) < 2:
            message = ws.receive_json()
            if message["type"] == "error":
                errors.append(message["message"])
            elif message["type"] == "pong":
                pongs.append(message["t"])
        assert len(errors) == len(hostile) + 1, errors
        assert all("\n" not in e and len(e) <= 200 for e in errors)
        assert any("binary" in e for e in errors) and any("nested" in e for e in errors)
        assert pongs == [None, 7]  # a non-finite time is not echoed back
    assert runner.running and runner.latest()["recognition"]["command"] is None


def test_the_motion_line_reads_the_arms_measured_motion() -> None:
    """A pose move (going home) commands no twist, yet the arm moves: the panel's speed is
    the arm's measured TCP twist, the commanded one only before any arm state."""
    from types import SimpleNamespace

    import numpy as np

    from wovenskin.ui.dashboard.snapshot import motion_part

    robot = SimpleNamespace(tcp_twist=np.array([0.12, 0.16, 0.0, 0.0, 0.0, 0.1]))
    state = SimpleNamespace(robot=robot, twist=np.zeros(6), gesture=None)
    moving = motion_part(SimpleNamespace(state=state, now=1.0))
    assert moving["linear_mm_s"] == 200.0 and moving["angular_deg_s"] == 5.7
    before = SimpleNamespace(robot=None, twist=np.array([0.05, 0, 0, 0, 0, 0]), gesture=None)
    assert motion_part(SimpleNamespace(state=before, now=1.0))["linear_mm_s"] == 50.0
