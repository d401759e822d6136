"""The safe executor on the real TurtleBot4Navigator and the simulator over DDS: results are the navigator's own
TaskResult, a goal Nav2 fails stops the plan with the server's error, and a stop request from another thread is
acted on by the executing thread, which cancels the goal itself."""

from __future__ import annotations

import threading

from nav_msgs.msg import Odometry
from rclpy.qos import qos_profile_sensor_data

from tb4.language.executor import ExecutionReport, execute_plan, plan_program
from tb4.language.world_context import pose_checker
from tb4.navigator import TaskResult
from tb4.sim.world import load_world

from .test_navigator_failures import _deep_inside_a_wall
from .test_navigator_tasks import make_navigator, start_localized

__all__ = ["make_navigator"]  # the fixture, imported for this module's tests

WORLD = "warehouse"


def test_executor_drives_the_real_navigator_and_stops_on_its_failures(start_simulator, ros, make_navigator) -> None:
    # a fixed rate: at --rate max the long goal below can end (in under a wall second) before the stop is sent
    start_simulator("--rate", "20", "--world", WORLD)
    odom = ros.latest(Odometry, "odom", qos_profile_sensor_data)  # matched long before it is needed
    nav = make_navigator()
    start_localized(nav)
    check = pose_checker(load_world(WORLD))

    plan = plan_program(
        "navigator.spin(0.5)\n"
        "navigator.startToPose(navigator.getPoseStamped([-1.0, -1.0], TurtleBot4Directions.NORTH))\n"
        "navigator.info('arrived')",
        None,
        check,
    )
    report = execute_plan(plan, nav)
    assert report.ok, report.stopped
    assert nav.getResult() is TaskResult.SUCCEEDED

    # A goal our planner would refuse (inside a wall) planned without the check, to reach Nav2: it fails there.
    x, y = _deep_inside_a_wall(WORLD)
    plan = plan_program(f"navigator.startToPose(navigator.getPoseStamped([{x}, {y}], 0))\nnavigator.spin(1.0)")
    report = execute_plan(plan, nav)
    assert report.completed == 0 and "ended FAILED (error 206" in report.stopped, report.stopped
    assert nav.getResult() is TaskResult.FAILED

    # Stop from another thread while a long goal runs: the executing thread cancels it, the robot stops.
    far = "navigator.startToPose(navigator.getPoseStamped([-13.0, 9.0], 0))\nnavigator.spin(1.0)"
    plan = plan_program(far, None, check)
    stop = threading.Event()
    reports: list[ExecutionReport] = []
    worker = threading.Thread(target=lambda: reports.append(execute_plan(plan, nav, stop=stop)), name="program")
    worker.start()
    try:
        ros.wait_for(odom, lambda m: abs(m.twist.twist.linear.x) > 0.1, timeout=60, what="robot moving")
    finally:
        stop.set()
        worker.join(30)
    assert not worker.is_alive()
    assert reports[0].completed == 0 and reports[0].stopped.endswith("cancelled: stopped on request")
    assert nav.getResult() is TaskResult.CANCELED
    ros.wait_for(odom, lambda m: abs(m.twist.twist.linear.x) < 0.01, timeout=30, what="robot stopped")
