"""Route and pose figures: route planning on the shipped graphs against the grid planner for the same trip, and
`tb4 pose` against a bare rclpy process (what starting any ROS command costs)."""

from __future__ import annotations

import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "src"))

from tb4.nav.costmap import GlobalCostmap  # noqa: E402
from tb4.nav.params import load_nav2_params  # noqa: E402
from tb4.nav.planner import Planner  # noqa: E402
from tb4.nav.route_graph import load_route_graph  # noqa: E402
from tb4.nav.route_planner import RoutePlanner, RouteRequest  # noqa: E402
from tb4.processes import ManagedProcess, claim_domain_id, ros_environment, tb4_command  # noqa: E402
from tb4.sim.world import load_world  # noqa: E402

__all__ = ["run"]

TRIPS = {"maze": ((-0.7, 0.0, 0.0), (9.0, 9.0, 0.0)), "warehouse": ((-0.7, 0.0, 0.0), (2.0, -23.0, 0.0))}


def _best(fn, n: int) -> float:  # type: ignore[no-untyped-def]
    times = []
    for _ in range(n):
        start = time.perf_counter()
        fn()
        times.append(time.perf_counter() - start)
    return min(times)


def _route_rows(n: int) -> list[dict]:
    rows = []
    params = load_nav2_params()
    for name, (start, goal) in TRIPS.items():
        world = load_world(name)
        assert world.route_graph is not None
        routes = RoutePlanner(load_route_graph(world.route_graph), params.section("route_server", "ros__parameters"))
        costmap = GlobalCostmap(world.map, params.costmap_params("global")).costmap
        request = RouteRequest(start=start, goal=goal, use_poses=True)
        ours = _best(lambda r=routes, q=request, c=costmap: r.densify(r.find_route(q, None, c)), n)
        grid = Planner(tolerance=0.5, allow_unknown=True)
        base = _best(lambda g=grid, c=costmap, s=start, e=goal: g.plan(c, s, e), n)
        rows.append(
            {
                "name": f"compute_route + dense path ({name})",
                "ours": ours * 1000,
                "baseline": base * 1000,
                "baseline_name": "grid planner, same trip",
                "unit": "ms",
                "ratio": base / ours,
                "goal": "cheaper than grid planning",
            }
        )
    return rows


def _pose_row(n: int) -> dict:
    env = ros_environment(claim_domain_id())
    sim = ManagedProcess(
        tb4_command("sim", "--rate", "max"),
        env=env,
        log_path=Path(tempfile.mkstemp(suffix=".log")[1]),
    )
    try:
        if not sim.wait_for_output("tb4 sim ready", 60):
            raise RuntimeError(f"simulator did not start: {sim.output()[-500:]}")

        def timed(args: list[str]) -> float:
            start = time.monotonic()
            subprocess.run(args, env=env, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, timeout=60)
            return time.monotonic() - start

        py = sys.executable
        pose = statistics.median(timed(tb4_command("pose", str(i % 3), "1")) for i in range(n))
        bare = statistics.median(
            timed([py, "-c", "import rclpy; rclpy.init(); rclpy.create_node('bench'); rclpy.shutdown()"])
            for _ in range(n)
        )
    finally:
        sim.stop()
    return {
        "name": "tb4 pose to a running simulator",
        "ours": pose,
        "baseline": bare,
        "baseline_name": "bare rclpy node process",
        "unit": "s",
        "ratio": bare / pose,
        "goal": "no fixed waits (was ~3 s + warning)",
    }


def run(quick: bool = False) -> list[dict]:
    return [*_route_rows(5 if quick else 20), _pose_row(3 if quick else 7)]


if __name__ == "__main__":
    for row in run(quick="--quick" in sys.argv):
        print(row)
