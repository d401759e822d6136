"""The live web viewer against a fleet (`tb4 sim --robots 3`, then `tb4 view` as a user runs them): every robot
drawn in its own colour where it truly is, every dock of the world drawn, and the tools commanding the robot picked
on the map or in the fleet legend."""

from __future__ import annotations

import math
import os
import re
import time
from collections.abc import Iterator
from typing import Any

import pytest

pytest.importorskip("rclpy", reason="ROS 2 wheels not installed")

from geometry_msgs.msg import PoseWithCovarianceStamped  # noqa: E402
from irobot_create_msgs.action import Undock  # noqa: E402
from irobot_create_msgs.msg import DockStatus  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from rclpy.qos import qos_profile_sensor_data  # noqa: E402

from tb4.processes import ManagedProcess, remove_stale_shm, ros_environment, shm_snapshot, tb4_command  # noqa: E402

from .test_viewer_browser import (  # noqa: E402 - the one-robot viewer test's browser, page helpers, settings
    LATCHED,
    SUCCEEDED,
    Run,
    browser_page,
)

# one module-scoped simulator serves every test here: pytest-xdist keeps them on one worker (--dist loadgroup)
pytestmark = pytest.mark.xdist_group("viewer_fleet")

FLEET = ("/robot1", "/robot2", "/robot3")
DOCKS = {"/robot1": (0.0, 0.0), "/robot2": (0.0, 1.0), "/robot3": (0.0, -1.0)}  # warehouse's first three docks


def _xy(msg: Odometry) -> tuple[float, float]:
    return (msg.pose.pose.position.x, msg.pose.pose.position.y)


def _hex_rgb(color: str) -> tuple[int, int, int]:
    return int(color[1:3], 16), int(color[3:5], 16), int(color[5:7], 16)


class FleetRun(Run):
    """The fleet's simulator, `tb4 view`, a ROS client watching every robot's ground truth, and the page."""

    def __init__(self, sim: ManagedProcess, viewer: ManagedProcess, url: str, ros: Any, page: Any) -> None:
        super().__init__(sim, viewer, url, ros, page)
        self.truth = {ns: ros.latest(Odometry, f"{ns}/ground_truth") for ns in FLEET}
        self.amcl_of = {ns: ros.latest(PoseWithCovarianceStamped, f"{ns}/amcl_pose", LATCHED) for ns in FLEET}
        self.dock_of = {ns: ros.latest(DockStatus, f"{ns}/dock_status", qos_profile_sensor_data) for ns in FLEET}

    def true_xy(self, namespace: str) -> tuple[float, float]:
        return _xy(self.ros.wait_for(self.truth[namespace], what=f"{namespace}/ground_truth"))


@pytest.fixture(scope="module")
def fleet(tmp_path_factory: pytest.TempPathFactory, e2e_ros_class: Any) -> Iterator[FleetRun]:
    env = ros_environment(int(os.environ["ROS_DOMAIN_ID"]))
    logs = tmp_path_factory.mktemp("viewer_fleet")
    before = shm_snapshot()
    started: list[ManagedProcess] = []
    ros = e2e_ros_class("viewer_fleet_e2e_client")
    try:
        sim = ManagedProcess(
            tb4_command("sim", "--robots", "3", "--rate", "5", "--world", "warehouse", "--localization", "truth"),
            env=env,
            log_path=logs / "sim.log",
        )
        started.append(sim)
        assert sim.wait_for_output("tb4 sim ready", 90), sim.output()
        viewer = ManagedProcess(tb4_command("view", "--port", "0"), env=env, log_path=logs / "view.log")
        started.append(viewer)
        assert viewer.wait_for_output("tb4 view serving", 60), viewer.output()
        match = re.search(r"serving (http://127\.0\.0\.1:\d+/)", viewer.output())
        assert match, viewer.output()
        with browser_page(match.group(1)) as page:
            yield FleetRun(sim, viewer, match.group(1), ros, page)
    finally:
        ros.close()
        for proc in reversed(started):
            proc.stop()
        remove_stale_shm(before)


def test_every_robot_is_drawn_in_its_own_colour_where_it_truly_is(fleet: FleetRun) -> None:
    fleet.wait_page(
        "S.namespace === '/robot1' && S.layers.map && S.robot && S.fleet.length === 3"
        " && S.fleet.every(r => r.picked || r.robot)",
        "the whole fleet, commanding /robot1 (the first robot: `tb4 view` was given no namespace)",
    )
    assert fleet.state("S.fleet.map(r => r.namespace)") == list(FLEET)
    assert fleet.state("S.fleet.map(r => r.picked)") == [True, False, False]
    colors = fleet.state("S.fleet.map(r => r.color)")
    assert len(set(colors)) == 3 and fleet.state("S.color") == colors[0]
    assert fleet.page.locator("#fleet li").all_inner_texts()[0].startswith("/robot1")

    drawn = {ns: fleet.state(f"S.fleet.find(r => r.namespace === '{ns}').robot") for ns in FLEET[1:]}
    drawn["/robot1"] = fleet.state("S.robot")
    for ns in FLEET:
        truth = fleet.true_xy(ns)
        assert truth == pytest.approx(DOCKS[ns], abs=0.05)
        assert (drawn[ns]["x"], drawn[ns]["y"]) == pytest.approx(truth, abs=0.05), ns

    fleet.view(0.0, 0.0, 60.0)
    screens = {s["namespace"]: s for s in fleet.state("S.fleetScreen")}
    assert sorted(screens) == sorted(FLEET)
    seen = []
    for ns, color in zip(FLEET, colors, strict=True):
        tx, ty = fleet.true_xy(ns)
        px, py = fleet.page.evaluate(f"tb4View.worldToScreen({tx}, {ty})")
        assert (screens[ns]["x"], screens[ns]["y"]) == pytest.approx((px, py), abs=3.0), ns  # 0.05 m at 60 px/m
        rgb = fleet.pixel(px, py)
        assert all(abs(a - b) <= 12 for a, b in zip(rgb, _hex_rgb(color), strict=True)), (ns, rgb, color)
        seen.append(rgb)
    assert len(set(seen)) == 3, seen


def _commanding(fleet: FleetRun, namespace: str) -> None:
    """The page commands `namespace` (however it was picked): marked in the fleet and the legend, in its colour,
    the other robots still drawn."""
    index = FLEET.index(namespace)
    fleet.wait_page(f"S.namespace === '{namespace}' && S.robot && S.fleet.length === 3", f"{namespace} commanded")
    assert fleet.state("S.fleet.map(r => r.picked)") == [i == index for i in range(len(FLEET))]
    assert fleet.state("S.color") == fleet.state(f"S.fleet[{index}].color")
    assert fleet.page.inner_text("#fleet li.picked").startswith(namespace)
    others = " && ".join(f"S.fleet[{i}].robot" for i in range(len(FLEET)) if i != index)
    fleet.wait_page(others, "the other robots still drawn")


def _pick_in_legend(fleet: FleetRun, namespace: str) -> None:
    """Click `namespace`'s entry in the fleet legend, as a user picks a robot there."""
    fleet.page.click(f"#fleet li[data-namespace='{namespace}']")
    _commanding(fleet, namespace)


def _localize_robot2(fleet: FleetRun) -> None:
    """Robot 2 (commanded) localized: with the page's 2D Pose Estimate on its dock, unless it already is."""
    if fleet.amcl_of["/robot2"]() is None:
        fleet.drag_tool("pose", *DOCKS["/robot2"], 0.0)
        fleet.ros.wait_for(fleet.amcl_of["/robot2"], what="/robot2/amcl_pose after the page's pose estimate")


def _undock_robot2(fleet: FleetRun) -> None:
    result = fleet.ros.result(fleet.ros.send_goal(Undock, "/robot2/undock", Undock.Goal()))
    assert result.status == SUCCEEDED


def _goal_moves_only_robot2(fleet: FleetRun, goal: tuple[float, float, float]) -> None:
    """With robot 2 commanded, localized and undocked: the Nav2 Goal tool drives it to `goal`, no other robot
    moves, and the page draws it there."""
    still = {ns: fleet.true_xy(ns) for ns in ("/robot1", "/robot3")}
    acks = fleet.state("S.acks.length")
    fleet.drag_tool("goal", *goal)
    fleet.wait_page(f"S.acks.length > {acks} && S.acks[S.acks.length - 1].command === 'goal'", "the goal ack")
    fleet.wait_page(
        f"S.goal && Math.hypot(S.goal.x - ({goal[0]}), S.goal.y - ({goal[1]})) < 0.05"
        " && S.task && S.task.action === 'navigate_to_pose'",
        "robot 2's goal and task",
    )
    moved = dict.fromkeys(still, 0.0)
    deadline = time.monotonic() + 120.0
    while time.monotonic() < deadline:
        for ns, start in still.items():
            moved[ns] = max(moved[ns], math.dist(fleet.true_xy(ns), start))
        if math.dist(fleet.true_xy("/robot2"), goal[:2]) < 0.3:
            break
        time.sleep(0.05)
    assert math.dist(fleet.true_xy("/robot2"), goal[:2]) < 0.3, "robot 2 never reached the page's goal"
    assert max(moved.values()) < 1e-3, moved  # robots 1 and 3 never moved
    fleet.wait_page("S.task && S.task.status === 'succeeded'", "robot 2's goal succeeded")
    fleet.wait_page(
        f"Math.hypot(S.robot.x - ({goal[0]}), S.robot.y - ({goal[1]})) < 0.3 && S.trail.length > 10",
        "robot 2 drawn at its goal with its trail",
    )
    assert fleet.state("S.fleet[0].task") is None or fleet.state("S.fleet[0].task.action") != "navigate_to_pose"


def test_pick_robot2_on_the_map_and_its_goal_moves_only_robot2(fleet: FleetRun) -> None:
    fleet.wait_page("S.fleet.length === 3 && S.fleetScreen.length === 3", "the fleet drawn")
    fleet.view(-1.0, 0.5, 60.0)
    x2, y2 = fleet.page.evaluate("(() => { const r = tb4State.fleet[1].robot; return [r.x, r.y]; })()")
    fleet.page.click("#tool-pan")
    fleet.page.mouse.click(*fleet.page_xy(x2, y2))  # a click on robot 2's body picks it
    _commanding(fleet, "/robot2")
    _localize_robot2(fleet)
    _undock_robot2(fleet)
    _goal_moves_only_robot2(fleet, (-3.0, 1.5, math.pi / 2))


def test_pick_robot2_in_the_legend_and_its_goal_moves_only_robot2(fleet: FleetRun) -> None:
    fleet.wait_page("S.fleet.length === 3 && S.fleetScreen.length === 3", "the fleet drawn")
    if fleet.state("S.namespace") == "/robot2":  # whatever ran before: start from another robot
        _pick_in_legend(fleet, "/robot1")
    fleet.view(-1.5, -0.5, 45.0)
    _pick_in_legend(fleet, "/robot2")
    _localize_robot2(fleet)
    if fleet.ros.wait_for(fleet.dock_of["/robot2"], what="/robot2/dock_status").is_docked:  # run alone: the
        _undock_robot2(fleet)  # map test's goal, which leaves robot 2 undocked, did not run first
    _goal_moves_only_robot2(fleet, (-3.0, -2.0, math.pi))


def test_every_dock_of_the_world_is_drawn_where_the_world_puts_it(fleet: FleetRun) -> None:
    fleet.wait_page("S.layers.map && S.world && S.world.name === 'warehouse'", "the warehouse")
    fleet.check_docks_drawn("warehouse")
