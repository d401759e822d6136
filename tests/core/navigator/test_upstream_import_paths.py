"""Existing scripts' imports resolve to our classes (thin re-export modules), without starting anything."""

from __future__ import annotations

import pytest

pytest.importorskip("nav2_msgs.action", reason="interface packages not built")


def test_upstream_modules_re_export_ours() -> None:
    import tb4.navigator as ours
    from nav2_simple_commander.costmap_2d import PyCostmap2D
    from nav2_simple_commander.footprint_collision_checker import LETHAL_OBSTACLE, FootprintCollisionChecker
    from nav2_simple_commander.line_iterator import LineIterator
    from nav2_simple_commander.robot_navigator import BasicNavigator, RunningTask, TaskResult
    from nav2_simple_commander.utils import euler_to_quaternion
    from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Directions, TurtleBot4Navigator

    assert BasicNavigator is ours.BasicNavigator and TaskResult is ours.TaskResult
    assert RunningTask is ours.RunningTask and RunningTask.COMPUTE_AND_TRACK_ROUTE.value == 12
    assert euler_to_quaternion is ours.utils.euler_to_quaternion
    assert TurtleBot4Navigator is ours.TurtleBot4Navigator and TurtleBot4Directions is ours.TurtleBot4Directions
    assert issubclass(TurtleBot4Navigator, BasicNavigator)
    assert PyCostmap2D is ours.PyCostmap2D and LineIterator is ours.LineIterator
    assert FootprintCollisionChecker is ours.FootprintCollisionChecker and LETHAL_OBSTACLE == 254


def test_the_upstream_api_is_complete() -> None:
    from tb4.navigator import BasicNavigator, TurtleBot4Navigator

    basic = [
        "setInitialPose",
        "goToPose",
        "goThroughPoses",
        "followWaypoints",
        "followPath",
        "spin",
        "backup",
        "driveOnHeading",
        "assistedTeleop",
        "dockRobotByPose",
        "dockRobotByID",
        "undockRobot",
        "cancelTask",
        "isTaskComplete",
        "getFeedback",
        "getResult",
        "getTaskError",
        "getPath",
        "getPathThroughPoses",
        "smoothPath",
        "changeMap",
        "clearAllCostmaps",
        "clearLocalCostmap",
        "clearGlobalCostmap",
        "getGlobalCostmap",
        "getLocalCostmap",
        "waitUntilNav2Active",
        "lifecycleStartup",
        "lifecycleShutdown",
        "destroyNode",
        "info",
        "warn",
        "error",
        "debug",
    ]
    tb4_extra = [
        "getPoseStamped",
        "stampPose",
        "createPath",
        "getDockedStatus",
        "dock",
        "undock",
        "startToPose",
        "startThroughPoses",
        "startFollowWaypoints",
    ]
    assert [m for m in basic if not callable(getattr(BasicNavigator, m, None))] == []
    assert [m for m in tb4_extra if not callable(getattr(TurtleBot4Navigator, m, None))] == []
