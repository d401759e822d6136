"""Run one build step and append how long it took to a log, so the install can say where its time goes.

CMake wraps each interface package's configure, build and install step with this (see CMakeLists.txt), and
tools/install.sh prints the log at the end. Standard library only: it runs before anything else is installed.

    python tools/time_step.py LOG LABEL -- COMMAND [ARG ...]
"""

from __future__ import annotations

import subprocess
import sys
import time

__all__ = ["main"]


def main(argv: list[str]) -> int:
    """Run COMMAND, append "LABEL SECONDS" to LOG (even when it fails) and return COMMAND's exit code."""
    if len(argv) < 4 or argv[2] != "--":
        print("usage: time_step.py LOG LABEL -- COMMAND [ARG ...]", file=sys.stderr)
        return 2
    log, label, command = argv[0], argv[1], argv[3:]
    start = time.monotonic()
    code = subprocess.call(command)
    with open(log, "a", encoding="utf-8") as out:
        out.write(f"{label} {time.monotonic() - start:.1f}\n")
    return code


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
