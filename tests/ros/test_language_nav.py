"""natural_language_nav end to end over DDS: the real simulator, the tutorial process with gpt_node, our own
OpenAI-compatible server on 127.0.0.1 driven through the real `openai` SDK, and commands published on user_input."""

from __future__ import annotations

import math
import sys
import time
from pathlib import Path

from geometry_msgs.msg import PoseWithCovarianceStamped
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import Bool, String

from tb4.language.scripted_server import Reply, ScriptedServer
from tb4.processes import tb4_command

LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE)
SECRET = "sk-test-DDSSECRETKEY00112233445566"
WOOD = "navigator.startToPose(navigator.getPoseStamped(destinations['wood crate'][0:2], destinations['wood crate'][2]))"
DOCK = (
    "navigator.startToPose(navigator.getPoseStamped(destinations['dock'][0:2], destinations['dock'][2]))\n"
    "navigator.dock()"
)

WEDGE = (
    "A0 = [1, 2, 3, 4]\n"
    + "".join(f"A{i} = [A{i - 1}, A{i - 1}, A{i - 1}, A{i - 1}]\n" for i in range(1, 21))
    + "navigator.info(A20)"
)


def scripted_model(pwned: Path):
    """Answers like a model would: a program for the last '# command' of the prompt."""

    def answer(body: dict) -> Reply | str:
        command = body["messages"][-1]["content"].rstrip().splitlines()[-1].lower()
        if "wooden" in command:
            return f"```python\n{WOOD}\n```"
        if "hostile" in command:
            return f"navigator.undock()\nimport os\nos.system('touch {pwned}')"
        if "wedge" in command:  # 4**21 leaves from tiny shared lists: once hung the planner
            return WEDGE
        if "again" in command:  # already docked: the dock fails, so the goal after it must not run
            return f"navigator.dock()\n{WOOD}"
        if "dunder" in command:
            return f"navigator.info(().__class__.__bases__[0].__subclasses__())\nopen('{pwned}', 'w')"
        if "dock" in command:
            return DOCK
        return Reply(status=400, error="unexpected command in the test")

    return answer


def start_tutorial(start_process, ros_env: dict[str, str], server: ScriptedServer, *options: str, name: str):
    args = [
        sys.executable,
        "-m",
        "tb4.tutorials.natural_language_nav",
        "--backend",
        "openai",
        "--base-url",
        server.base_url,
        "--model-name",
        "scripted-model",
        "--timeout",
        "20",
        "--max-retries",
        "1",
        *options,
    ]
    proc = start_process(args, name=name, env={**ros_env, "OPENAI_API_KEY": SECRET})
    if not proc.wait_for_output("natural_language_nav ready", timeout=120):
        raise AssertionError(f"tutorial did not become ready:\n{proc.output()}")
    return proc


def wait_output(proc, text: str, timeout: float = 120.0) -> None:
    if not proc.wait_for_output(text, timeout=timeout):
        raise AssertionError(f"{text!r} never appeared in the output:\n{proc.output()}")


def wait_exit(proc, timeout: float = 60.0) -> int:
    deadline = time.monotonic() + timeout
    while proc.alive() and time.monotonic() < deadline:
        time.sleep(0.1)
    assert not proc.alive(), f"the tutorial did not exit after its commands:\n{proc.output()}"
    return int(proc.popen.returncode)


def publisher(ros):
    pub = ros.node.create_publisher(String, "user_input", 10)
    deadline = time.monotonic() + 30.0
    while pub.get_subscription_count() == 0:
        assert time.monotonic() < deadline, "gpt_node never subscribed to user_input"
        time.sleep(0.05)
    time.sleep(0.3)
    return pub


def xy(msg: PoseWithCovarianceStamped) -> tuple[float, float]:
    return (msg.pose.pose.position.x, msg.pose.pose.position.y)


def near(target: tuple[float, float], tol: float = 0.3):
    return lambda m: math.dist(xy(m), target) <= tol


def test_parking_brake_logs_the_program_and_only_the_allowed_publisher_is_heard(
    start_simulator, start_process, ros, ros_env, tmp_path
) -> None:
    start_simulator("--rate", "max", "--world", "depot")
    pose = ros.latest(PoseWithCovarianceStamped, "amcl_pose", LATCHED)
    ready = ros.latest(Bool, "ready_for_input")
    with ScriptedServer(scripted_model(tmp_path / "pwned")) as server:
        proc = start_tutorial(
            start_process, ros_env, server, "--allowed-publisher", "/tb4_say", "--max-commands", "1", name="parked"
        )
        wait_output(proc, "parking brake ON")
        ros.wait_for(ready, lambda m: m.data is True, timeout=30, what="ready_for_input true")
        start = xy(ros.wait_for(pose, timeout=30, what="amcl_pose"))

        publisher(ros).publish(String(data="Go to the wooden object"))  # from /test_client: not allowed
        wait_output(proc, "Ignoring a command from /test_client", timeout=30)
        assert server.requests == [], "a command from a node that is not allowed must not reach the model"

        say = start_process(
            tb4_command("say", "Go", "to", "the", "wooden", "object", "--timeout", "30"),
            name="say",
        )
        wait_output(say, "published on /user_input")
        wait_output(proc, "Parking brake is on: not executing")
        assert wait_exit(proc) == 0
    output = proc.output()
    assert "destinations['wood crate']" in output  # the program is logged
    assert len(server.requests) == 1
    prompt = server.requests[0]["body"]["messages"][-1]["content"]
    assert prompt.rstrip().endswith("# Go to the wooden object") and "'wood crate': [0, 3, 0]" in prompt
    time.sleep(1.0)
    assert math.dist(xy(pose()), start) < 0.1, "the robot moved with the parking brake on"
    assert SECRET not in output


def test_model_program_drives_the_robot_hostile_programs_are_refused(
    start_simulator, start_process, ros, ros_env, tmp_path
) -> None:
    start_simulator("--rate", "max", "--world", "depot")
    pose = ros.latest(PoseWithCovarianceStamped, "amcl_pose", LATCHED)
    ready_seen: list[bool] = []
    ros.node.create_subscription(Bool, "ready_for_input", lambda m: ready_seen.append(m.data), 10)
    pwned = tmp_path / "pwned"
    with ScriptedServer(scripted_model(pwned)) as server:
        proc = start_tutorial(
            start_process, ros_env, server, "--parking-brake", "off", "--max-commands", "6", name="drive"
        )
        pub = publisher(ros)

        def command(text: str, done: str) -> None:
            seen = len(ready_seen)
            pub.publish(String(data=text))
            wait_output(proc, done)
            ros.wait_for(
                lambda: ready_seen[seen:] or None,
                lambda s: False in s and s[-1] is True and s.index(False) < len(s) - 1,
                timeout=30,
                what=f"ready_for_input false then true after {text!r}",
            )

        command("Go to the wooden object", "Done (1 steps)")
        arrived = ros.wait_for(pose, near((0.0, 3.0)), timeout=30, what="the robot at the wood crate")
        command("a hostile command", "Program refused, nothing was executed: line 2: imports are not allowed")
        command("a dunder command", "Program refused, nothing was executed")
        command("a wedge command", "Program refused, nothing was executed: line 6: value too large")
        time.sleep(0.5)
        assert math.dist(xy(pose()), xy(arrived)) < 0.1, "a refused program moved the robot"
        assert not pwned.exists()
        command("Dock", "Dock succeeded")  # the node answers after the wedge
        docked = xy(pose())
        command("dock again", "Stopped after 0/2 steps: dock did not succeed")
        time.sleep(0.5)
        assert math.dist(xy(pose()), docked) < 0.1, "the goal after a failed dock ran"
        assert wait_exit(proc) == 1, "the tutorial exits 1 when a command failed (here: the second dock)"
    assert len(server.requests) == 6
    output = proc.output()
    assert "Undocking" not in output.split("gpt_node ready")[1], "the hostile undock() must never run"
    assert SECRET not in output
    for request in server.requests:  # the key went to our server, as the Authorization header, only
        headers = {k.lower(): v for k, v in request["headers"].items()}
        assert headers["authorization"] == f"Bearer {SECRET}"
