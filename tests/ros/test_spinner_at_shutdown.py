"""rclpy.shutdown() with a node spun by a BackgroundSpinner returns at once, and the process then exits cleanly.

Upstream scripts end with rclpy.shutdown(), which destroys every node while it holds the context's lock. The
navigator's destroy_node stops its spinner; the spin thread waits for that same lock in context.ok(), so joining
it waited out the join's whole timeout (2 s at the end of every navigator script). Not joining at all let the
thread outlive the interpreter, which aborted the process ("terminate called without an active exception").
"""

from __future__ import annotations

import subprocess
import sys
import textwrap

PROGRAM = textwrap.dedent(
    """
    import time
    import rclpy
    from rclpy.node import Node
    from tb4.ros.background import BackgroundSpinner

    JOIN_TIMEOUT = 30.0  # s: a join that waits it out is plain to see

    class SpunNode(Node):
        def __init__(self):
            super().__init__("spun_at_shutdown")
            self.spinner = BackgroundSpinner(self, name="spun_at_shutdown")
            self.spinner.start()

        def destroy_node(self):
            self.spinner.stop(timeout=JOIN_TIMEOUT)
            super().destroy_node()

    rclpy.init()
    node = SpunNode()
    time.sleep(0.3)  # the thread is in its spin loop
    start = time.monotonic()
    rclpy.shutdown()
    print(f"shutdown took {time.monotonic() - start:.3f} s", flush=True)
    """
)


NAVIGATOR_SCRIPT = textwrap.dedent(
    """
    import rclpy
    from turtlebot4_navigation.turtlebot4_navigator import TurtleBot4Navigator

    rclpy.init()
    navigator = TurtleBot4Navigator()
    print("docked:", navigator.getDockedStatus(), flush=True)  # messages flowing into the spun node
    rclpy.shutdown()  # how upstream's scripts end
    print("shut down", flush=True)
    """
)


def run(program: str, env: dict[str, str]) -> str:
    done = subprocess.run([sys.executable, "-c", program], env=env, capture_output=True, text=True, timeout=120)
    output = done.stdout + done.stderr
    assert done.returncode == 0, output  # an abort at exit is -6
    assert "terminate called" not in output, output
    return output


def test_shutdown_does_not_wait_for_the_spin_thread(ros_env: dict[str, str]) -> None:
    output = run(PROGRAM, ros_env)
    took = float(output.split("shutdown took ", 1)[1].split()[0])
    assert took < 15.0, output  # far below the 30 s join timeout it used to wait out


def test_a_navigator_script_ending_with_rclpy_shutdown_exits_cleanly(start_simulator, ros_env: dict[str, str]) -> None:
    start_simulator("--world", "warehouse")  # real time: the script needs only dock_status flowing
    for _ in range(4):  # the abort came from a spin thread still running at exit, a race (2 of 4 runs): four tries
        output = run(NAVIGATOR_SCRIPT, ros_env)
        assert "docked: True" in output and "shut down" in output, output
