"""The live web viewer in a real headless Chromium against the real simulator: what it draws and what its tools do.

One simulator, one `tb4 view` process and one browser page serve the whole module (starting them is most of the
cost). Tests that need the robot localized and undocked get there through `ready_robot`, whatever ran before.
"""

from __future__ import annotations

import contextlib
import json
import math
import os
import re
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import numpy as np
import pytest

CHROMIUM = "/usr/bin/chromium"
if not Path(CHROMIUM).exists():
    pytest.skip(
        f"{CHROMIUM} is missing: run `bash tools/install_browser.sh` (Debian's chromium package) to test the viewer",
        allow_module_level=True,
    )
pytest.importorskip("rclpy", reason="ROS 2 wheels not installed")
playwright_api = pytest.importorskip("playwright.sync_api", reason="playwright is not installed")

from geometry_msgs.msg import PoseStamped, PoseWithCovarianceStamped  # noqa: E402
from irobot_create_msgs.action import Undock  # noqa: E402
from irobot_create_msgs.msg import DockStatus  # noqa: E402
from nav2_msgs.action import NavigateToPose  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data  # noqa: E402

from tb4.processes import ManagedProcess, remove_stale_shm, ros_environment, shm_snapshot, tb4_command  # noqa: E402
from tb4.sim.world import load_world  # noqa: E402

# one module-scoped simulator serves every test here: pytest-xdist keeps them on one worker (--dist loadgroup)
pytestmark = pytest.mark.xdist_group("viewer_browser")

BROWSER_ARGS = [
    "--headless=new",
    "--no-sandbox",
    "--disable-gpu",
    "--disable-quic",
    "--no-first-run",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
]


DOCK_RGB = (0xF4, 0xD3, 0x5E)  # COLORS.dock (static/js/state.js): the station body's fill
STATION_AHEAD = 0.25  # m: map_draw.js draws the station this far ahead of the docked robot's pose
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
SUCCEEDED = 4
WAIT = 60_000  # ms: generous, the machine is shared


def _yaw_quaternion(yaw: float) -> tuple[float, float]:
    return math.sin(yaw / 2.0), math.cos(yaw / 2.0)


def _quaternion_yaw(q: Any) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _angle_diff(a: float, b: float) -> float:
    return abs(math.remainder(a - b, 2 * math.pi))


class Run:
    """The module's simulator, viewer process, ROS client and browser page."""

    def __init__(self, sim: ManagedProcess, viewer: ManagedProcess, url: str, ros: Any, page: Any) -> None:
        self.sim, self.viewer, self.url, self.ros, self.page = sim, viewer, url, ros, page
        self.amcl = ros.latest(PoseWithCovarianceStamped, "amcl_pose", LATCHED)
        self.odom = ros.latest(Odometry, "odom", qos_profile_sensor_data)
        self.dock = ros.latest(DockStatus, "dock_status", qos_profile_sensor_data)
        self.initial_poses = ros.collect(PoseWithCovarianceStamped, "initialpose")

    def state(self, expression: str) -> Any:
        return self.page.evaluate(f"(() => {{ const S = window.tb4State; return {expression}; }})()")

    def wait_page(self, condition: str, what: str, timeout: int = WAIT) -> None:
        try:
            self.page.wait_for_function(
                f"(() => {{ const S = window.tb4State; return !!({condition}); }})()", timeout=timeout
            )
        except playwright_api.TimeoutError:
            raise AssertionError(f"the page never showed {what}; tb4State: {self.debug()}") from None

    def debug(self) -> str:
        return self.page.evaluate(
            "JSON.stringify({robot: tb4State.robot, task: tb4State.task, goal: tb4State.goal, "
            "errors: tb4State.errors, connected: tb4State.connected, states: tb4State.stateCount})"
        )

    def view(self, cx: float, cy: float, scale: float) -> None:
        """Set the view and wait for a frame drawn with it (counted in the same task as the change: a frame drawn
        between a separate count and the change would pass for it, with the old view)."""
        frames = self.page.evaluate(f"(() => {{ tb4View.setView({cx}, {cy}, {scale}); return tb4State.frames; }})()")
        self.wait_page(f"S.frames > {frames}", "a redraw")

    def page_xy(self, x: float, y: float) -> tuple[float, float]:
        px, py = self.page.evaluate(f"tb4View.worldToPage({x}, {y})")
        return float(px), float(py)

    def drag_tool(self, tool: str, x: float, y: float, yaw: float, length: float = 1.0) -> None:
        """Use a pose tool like a user: pick it, press at (x, y), drag towards the heading, release."""
        self.page.click(f"#tool-{tool}")
        x0, y0 = self.page_xy(x, y)
        x1, y1 = self.page_xy(x + length * math.cos(yaw), y + length * math.sin(yaw))
        self.page.mouse.move(x0, y0)
        self.page.mouse.down()
        self.page.mouse.move(x1, y1, steps=6)
        self.page.mouse.up()

    def pixel(self, px: float, py: float) -> tuple[int, int, int]:
        """The canvas colour at CSS pixel (px, py) of the canvas."""
        rgb = self.page.evaluate(
            f"""(() => {{
                const c = document.getElementById('view');
                const k = c.width / c.clientWidth;
                const d = c.getContext('2d').getImageData(Math.round({px} * k), Math.round({py} * k), 1, 1).data;
                return [d[0], d[1], d[2]];
            }})()"""
        )
        return int(rgb[0]), int(rgb[1]), int(rgb[2])

    def check_docks_drawn(self, world: str, scale: float = 100.0) -> None:
        """Every dock of `world` drawn, in order and labelled, where the world puts it: the page's record of each
        (S.docksScreen) holds the world's dock pose and its station's screen point, and the canvas there shows the
        station's colour. The scan layer is off meanwhile (its points may land on a station's face)."""
        docks = load_world(world).all_docks
        labels = ["dock"] if len(docks) == 1 else [f"dock {i + 1}" for i in range(len(docks))]
        scan = self.page.locator("input[data-layer=scan]")
        scan.uncheck()
        try:
            self.view(sum(d[0] for d in docks) / len(docks), sum(d[1] for d in docks) / len(docks), scale)
            drawn = self.state("S.docksScreen")
            assert [d["label"] for d in drawn] == labels, drawn
            width, height = self.page.evaluate(
                "(c => [c.clientWidth, c.clientHeight])(document.getElementById('view'))"
            )
            for (x, y, yaw), d in zip(docks, drawn, strict=True):
                assert (d["worldX"], d["worldY"], d["yaw"]) == pytest.approx((x, y, yaw), abs=1e-9), d
                sx, sy = x + STATION_AHEAD * math.cos(yaw), y + STATION_AHEAD * math.sin(yaw)
                px, py = self.page.evaluate(f"tb4View.worldToScreen({sx}, {sy})")
                assert (d["x"], d["y"]) == pytest.approx((px, py), abs=0.5), d
                # beside the station's axis: a robot docked there draws its heading line along the axis
                qx, qy = self.page.evaluate(
                    f"tb4View.worldToScreen({sx + 0.08 * math.sin(yaw)}, {sy - 0.08 * math.cos(yaw)})"
                )
                assert 0 < qx < width and 0 < qy < height, (d, width, height)
                rgb = self.pixel(qx, qy)
                assert all(abs(a - b) <= 12 for a, b in zip(rgb, DOCK_RGB, strict=True)), (d, rgb)
        finally:
            scan.check()

    def publish_initial_pose(self, x: float, y: float, yaw: float) -> None:
        pub = self.ros.node.create_publisher(PoseWithCovarianceStamped, "initialpose", 10)
        msg = PoseWithCovarianceStamped()
        msg.header.frame_id = "map"
        msg.pose.pose.position.x, msg.pose.pose.position.y = x, y
        msg.pose.pose.orientation.z, msg.pose.pose.orientation.w = _yaw_quaternion(yaw)
        deadline = time.monotonic() + 30
        while time.monotonic() < deadline:
            pub.publish(msg)
            amcl = self.amcl()
            if amcl is not None and math.hypot(amcl.pose.pose.position.x - x, amcl.pose.pose.position.y - y) < 0.05:
                return
            time.sleep(0.1)
        raise AssertionError("amcl_pose never answered the initial pose")


@contextlib.contextmanager
def browser_page(url: str) -> Iterator[Any]:
    """A headless Chromium page on `url` (every wait bounded by WAIT); the browser closes on the way out."""
    pw = playwright_api.sync_playwright().start()
    try:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=BROWSER_ARGS)
        try:
            page = browser.new_page(viewport={"width": 1280, "height": 800})
            page.set_default_timeout(WAIT)
            page.goto(url)
            yield page
        finally:
            browser.close()
    finally:
        pw.stop()


@pytest.fixture(scope="module")
def run(tmp_path_factory: pytest.TempPathFactory, e2e_ros_class: Any) -> Iterator[Run]:
    env = ros_environment(int(os.environ["ROS_DOMAIN_ID"]))
    logs = tmp_path_factory.mktemp("viewer")
    before = shm_snapshot()
    started: list[ManagedProcess] = []
    ros = e2e_ros_class("viewer_e2e_client")
    try:
        # Truth localization: these tests check what the page draws and sends (a pose set with the tool is drawn
        # exactly there); AMCL would pull a deliberately wrong pose toward the truth. Its particles are drawn in the
        # viewer's core tests.
        sim = ManagedProcess(
            tb4_command("sim", "--rate", "5", "--world", "warehouse", "--localization", "truth"),
            env=env,
            log_path=logs / "sim.log",
        )
        started.append(sim)
        viewer = ManagedProcess(tb4_command("view", "--port", "0"), env=env, log_path=logs / "view.log")
        started.append(viewer)
        assert sim.wait_for_output("tb4 sim ready", 60), sim.output()
        assert viewer.wait_for_output("tb4 view serving", 60), viewer.output()
        match = re.search(r"serving (http://127\.0\.0\.1:\d+/)", viewer.output())
        assert match, f"the viewer must serve on 127.0.0.1 by default:\n{viewer.output()}"
        with contextlib.ExitStack() as stack:
            try:
                page = stack.enter_context(browser_page(match.group(1)))
            except playwright_api.Error as exc:  # a stress run once saw "connection refused" here: say what ran
                raise AssertionError(
                    f"the page did not load: {exc}\nviewer alive: {viewer.alive()} "
                    f"(exit code {viewer.popen.returncode}); its output:\n{viewer.output()}\nsimulator alive: "
                    f"{sim.alive()} (exit code {sim.popen.returncode}); its output:\n{sim.output()[-3000:]}"
                ) from None
            yield Run(sim, viewer, match.group(1), ros, page)
    finally:
        ros.close()
        for proc in reversed(started):
            proc.stop()
        remove_stale_shm(before)


@pytest.fixture
def ready_robot(run: Run) -> Run:
    """Localized where the robot is, and undocked."""
    if run.amcl() is None:
        run.publish_initial_pose(0.0, 0.0, 0.0)
    if run.ros.wait_for(run.dock, what="dock_status").is_docked:
        result = run.ros.result(run.ros.send_goal(Undock, "undock", Undock.Goal()))
        assert result.status == SUCCEEDED
    return run


def _goal(x: float, y: float, yaw: float) -> NavigateToPose.Goal:
    goal = NavigateToPose.Goal()
    goal.pose = PoseStamped()
    goal.pose.header.frame_id = "map"
    goal.pose.pose.position.x, goal.pose.pose.position.y = x, y
    goal.pose.pose.orientation.z, goal.pose.pose.orientation.w = _yaw_quaternion(yaw)
    return goal


def _open_point(min_clearance: float, near: tuple[float, float], radius: float) -> tuple[float, float]:
    """A map point at least `min_clearance` from anything occupied, within `radius` of `near`."""
    from scipy.ndimage import distance_transform_edt

    grid = load_world("warehouse").map
    clearance = distance_transform_edt(~grid.occupied_mask()) * grid.resolution
    rows, cols = np.nonzero(clearance > min_clearance)
    xs = grid.origin_x + (cols + 0.5) * grid.resolution
    ys = grid.origin_y + (rows + 0.5) * grid.resolution
    d = np.hypot(xs - near[0], ys - near[1])
    ok = (d < radius) & (d > 2.0)
    i = int(np.argmin(np.where(ok, d, np.inf)))
    return float(xs[i]), float(ys[i])


def test_page_loads_and_draws_map_robot_scan_and_status(run: Run) -> None:
    run.wait_page("S.connected && S.layers.map && S.robot && S.scan.length > 0 && S.world", "map, robot and scan")
    grid = load_world("warehouse").map
    assert run.state("[S.layers.map.width, S.layers.map.height]") == [grid.width, grid.height]
    assert run.state("S.world.name") == "warehouse"
    assert run.state("S.world.destinations.map(d => d.name)") == list(load_world("warehouse").destinations)
    robot = run.state("S.robot")
    assert math.hypot(robot["x"], robot["y"]) < 0.05 and robot["radius"] == pytest.approx(0.175)

    run.view(0.0, 0.0, 40.0)
    # The pose estimate may move between the last draw and this read: compare the drawing with what it drew.
    screen = run.state("S.robotScreen")
    rx, ry = run.page.evaluate(f"tb4View.worldToScreen({screen['worldX']}, {screen['worldY']})")
    assert (screen["x"], screen["y"]) == pytest.approx((rx, ry), abs=0.5)
    assert math.hypot(screen["worldX"] - robot["x"], screen["worldY"] - robot["y"]) < 0.1
    r, g, b = run.pixel(rx, ry)
    assert b > 200 and b > r + 80, f"robot centre should be drawn blue, got {(r, g, b)}"
    fx, fy = _open_point(1.2, near=(0.0, 0.0), radius=8.0)
    free = run.pixel(*run.page.evaluate(f"tb4View.worldToScreen({fx}, {fy})"))
    assert min(free) > 225, f"open floor at ({fx:.2f}, {fy:.2f}) should be drawn near white, got {free}"
    rows, cols = np.nonzero(grid.occupied_mask())
    wx, wy = grid.origin_x + (cols + 0.5) * grid.resolution, grid.origin_y + (rows + 0.5) * grid.resolution
    i = int(np.argmin(np.hypot(wx, wy)))  # the occupied cell nearest the robot (in view)
    wall = run.pixel(*run.page.evaluate(f"tb4View.worldToScreen({wx[i]}, {wy[i]})"))
    assert sum(wall) < 450, f"an occupied cell should be drawn dark, got {wall}"

    run.wait_page("S.simTime > 0 && S.rtf > 0 && S.battery && S.dock", "the status")
    assert run.page.inner_text("#dock") in ("docked", "undocked", "undocked, dock in view")
    assert "%" in run.page.inner_text("#battery")
    assert run.page.inner_text("#sim-time") != "–" and run.page.inner_text("#rtf").endswith("×")


def test_every_dock_of_the_world_is_drawn_where_the_world_puts_it(run: Run) -> None:
    run.wait_page("S.connected && S.layers.map && S.world && S.world.name === 'warehouse'", "the warehouse")
    run.check_docks_drawn("warehouse")


def test_pose_tool_click_drag_publishes_initialpose_like_rviz(run: Run) -> None:
    run.wait_page("S.connected && S.layers.map", "the map")
    run.view(0.5, 0.5, 60.0)
    count = len(run.initial_poses)
    msg = None
    for _attempt in range(3):  # on a loaded 2-core machine DDS discovery can lag: a user would drag again
        run.drag_tool("pose", 0.5, 0.5, math.pi / 2)
        try:
            msg = run.ros.wait_for(
                lambda: run.initial_poses[count] if len(run.initial_poses) > count else None,
                timeout=10.0,
                what="initialpose from the page",
            )
            break
        except Exception:  # noqa: BLE001 - timed out: try the tool once more
            continue
    assert msg is not None, "the page's pose tool never produced an initialpose"
    assert msg.header.frame_id == "map"
    assert msg.pose.pose.position.x == pytest.approx(0.5, abs=0.03)
    assert msg.pose.pose.position.y == pytest.approx(0.5, abs=0.03)
    assert _angle_diff(_quaternion_yaw(msg.pose.pose.orientation), math.pi / 2) < 0.05
    assert msg.pose.covariance[0] == pytest.approx(0.25) and msg.pose.covariance[35] > 0
    run.wait_page(
        "S.robot.localized && Math.abs(S.robot.x - 0.5) < 0.05 && Math.abs(S.robot.y - 0.5) < 0.05",
        "the robot drawn at the estimated pose",
    )
    assert run.state("S.tool") == "pan"  # like RViz, the tool is used once

    run.drag_tool("pose", 0.0, 0.0, 0.0)  # now the true pose (the robot is on its dock)
    run.wait_page("Math.hypot(S.robot.x, S.robot.y) < 0.05 && Math.abs(S.robot.yaw) < 0.05", "the corrected pose")
    amcl = run.ros.wait_for(
        run.amcl,
        lambda m: math.hypot(m.pose.pose.position.x, m.pose.pose.position.y) < 0.05,
        what="amcl_pose at the dock",
    )
    assert _angle_diff(_quaternion_yaw(amcl.pose.pose.orientation), 0.0) < 0.05


def test_drawn_robot_follows_a_navigation_goal(ready_robot: Run) -> None:
    run = ready_robot
    run.view(-1.5, -1.0, 45.0)
    goal = (-3.0, -2.0, math.pi)
    handle = run.ros.send_goal(NavigateToPose, "navigate_to_pose", _goal(*goal))
    result_future = handle.get_result_async()
    drawn: list[tuple[float, float]] = []
    deadline = time.monotonic() + 90
    while not result_future.done() and time.monotonic() < deadline:
        robot = run.state("S.robot")
        if robot and (not drawn or drawn[-1] != (robot["x"], robot["y"])):
            drawn.append((robot["x"], robot["y"]))
        time.sleep(0.03)
    assert result_future.done(), "navigation did not finish"
    assert result_future.result().status == SUCCEEDED
    run.wait_page(f"Math.hypot(S.robot.x - ({goal[0]}), S.robot.y - ({goal[1]})) < 0.3", "the robot at the goal")
    start_d = math.hypot(drawn[0][0] - goal[0], drawn[0][1] - goal[1])
    between = [p for p in drawn if 0.4 < math.hypot(p[0] - goal[0], p[1] - goal[1]) < start_d - 0.4]
    assert len(between) >= 2, f"the drawn robot should move along the way, saw {drawn}"
    run.wait_page(
        "S.task && S.task.action === 'navigate_to_pose' && S.task.status === 'succeeded'", "the finished task"
    )
    assert run.state("S.trail.length") >= 20 and run.state("S.plan.length") >= 4
    assert run.state("[S.goal.x, S.goal.y]") == pytest.approx(goal[:2], abs=0.01)
    # the robot is drawn where it is: at the next animation frame after its last pose (a loaded machine's browser
    # can be a frame or more behind the state)
    run.wait_page(
        "S.robotScreen && Math.hypot(S.robotScreen.worldX - S.robot.x, S.robotScreen.worldY - S.robot.y) < 0.1",
        "the robot drawn at its pose",
    )
    screen = run.state("S.robotScreen")
    expected = run.page.evaluate(f"tb4View.worldToScreen({screen['worldX']}, {screen['worldY']})")
    assert (screen["x"], screen["y"]) == pytest.approx(tuple(expected), abs=1.0)


def test_nav2_goal_tool_moves_the_robot(ready_robot: Run) -> None:
    run = ready_robot
    goal = (-3.0, 1.5, math.pi / 2)
    run.view(-2.0, 0.0, 45.0)
    acks = run.state("S.acks.length")
    run.drag_tool("goal", *goal)
    run.wait_page(f"S.acks.length > {acks} && S.acks[S.acks.length - 1].command === 'goal'", "the goal ack")
    sent = run.state("S.acks[S.acks.length - 1].pose")
    assert (sent["x"], sent["y"]) == pytest.approx(goal[:2], abs=0.03)
    # position and heading in one wait: on its way the robot passes within 0.3 m of the goal still facing the way it
    # drives (a loaded machine's amcl_pose caught it there), and turns to the dragged heading only at the goal
    run.ros.wait_for(
        run.amcl,
        lambda m: (
            math.hypot(m.pose.pose.position.x - goal[0], m.pose.pose.position.y - goal[1]) < 0.3
            and _angle_diff(_quaternion_yaw(m.pose.pose.orientation), goal[2]) < 0.4
        ),
        timeout=90,
        what="the robot at the page's goal, facing the dragged heading",
    )
    run.wait_page("S.task && S.task.status === 'succeeded'", "the goal succeeded")


def test_cancel_button_stops_navigation(ready_robot: Run) -> None:
    run = ready_robot
    target = load_world("warehouse").destinations["packing station"]
    run.page.evaluate(f"tb4Send({{type: 'goal', x: {target.x}, y: {target.y}, yaw: 0}})")
    run.wait_page("S.task && S.task.active && S.task.distance_remaining > 1", "the running task")
    run.ros.wait_for(run.odom, lambda m: abs(m.twist.twist.linear.x) > 0.05, what="the robot moving")
    run.page.click("#cancel")
    run.wait_page("S.task && S.task.status === 'canceled'", "the canceled task")
    run.ros.wait_for(run.odom, lambda m: abs(m.twist.twist.linear.x) < 0.01, what="the robot stopped")


def test_malformed_messages_are_rejected_and_the_viewer_keeps_serving(run: Run) -> None:
    run.wait_page("S.connected", "a connection")
    replies = run.page.evaluate(
        """async () => {
            const ws = new WebSocket(`ws://${location.host}/ws`);
            const replies = [];
            await new Promise((ok, fail) => { ws.onopen = ok; ws.onerror = fail; });
            ws.onmessage = (e) => { const m = JSON.parse(e.data); if (m.type === 'error') replies.push(m.message); };
            ws.send('{"type": "goal", "x": ');
            ws.send(JSON.stringify({type: 'initial_pose', x: 'NaN', y: 0, yaw: 0}));
            ws.send('{"type": "goal", "x": NaN, "y": 0, "yaw": 0}');
            ws.send(JSON.stringify({type: 'launch_missiles'}));
            for (let i = 0; i < 100 && replies.length < 4; i++) await new Promise(r => setTimeout(r, 50));
            ws.close();
            return replies;
        }"""
    )
    assert len(replies) == 4, replies
    assert "not JSON" in replies[0] and "must be a number" in replies[1]
    assert "finite" in replies[2] and "unknown message type" in replies[3]
    count = run.state("S.stateCount")
    run.wait_page(f"S.stateCount > {count + 3}", "more updates after the bad messages")
    deadline = time.monotonic() + 20
    health: dict[str, Any] = {}
    while time.monotonic() < deadline:  # the closed socket is gone, the page's own remains
        health = json.loads(run.page.evaluate("fetch('/api/health').then(r => r.text())"))
        if health["pages"] == 1:
            break
        time.sleep(0.1)
    assert health["pages"] == 1, health
    assert run.viewer.alive()


def test_namespace_picker_shows_another_robot(run: Run, tmp_path: Path) -> None:
    env = ros_environment(int(os.environ["ROS_DOMAIN_ID"]))
    depot = load_world("depot").map
    with ManagedProcess(
        tb4_command("sim", "--rate", "10", "--world", "depot", "--namespace", "robot2"),
        env=env,
        log_path=tmp_path / "sim2.log",
    ) as sim2:
        assert sim2.wait_for_output("tb4 sim ready", 60), sim2.output()
        run.wait_page("S.namespaces.includes('/robot2')", "the second robot in the picker")
        run.page.select_option("#namespace", "/robot2")
        run.wait_page(
            "S.namespace === '/robot2' && S.layers.map && S.robot && S.world && S.world.name === 'depot'",
            "robot2's map, robot and world",
        )
        assert run.state("[S.layers.map.width, S.layers.map.height]") == [depot.width, depot.height]
        run.page.select_option("#namespace", "")
        run.wait_page("S.namespace === '' && S.layers.map && S.world && S.world.name === 'warehouse'", "robot 1 again")
