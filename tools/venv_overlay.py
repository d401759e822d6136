"""A virtual environment that overlays another one (its base), as a ROS overlay workspace overlays its underlay.

tools/install.sh copies this module into the overlay's site-packages, with a .pth file that calls activate() at
every interpreter start. The overlay holds only what differs from the base (the Jazzy wire environment: Nav2 Jazzy's
nav2_msgs and its editable install of the project); everything else (the ROS wheels, our other interface packages,
the Python dependencies) is the base's, so it is neither downloaded, unpacked nor built a second time.

What comes first is the overlay's, on every search path: Python's (the base's site-packages comes after the
overlay's), the dynamic loader's (LD_LIBRARY_PATH: a type support library of the overlay's nav2_msgs shadows the
base's of the same name) and ROS's (AMENT_PREFIX_PATH, where message definitions are read). The loader reads
LD_LIBRARY_PATH only when a process starts, so the first interpreter of a process tree sets the paths and starts
itself again; its children inherit them. The base's own start-up hook (the ROS wheels' bootstrapper, which would
put the same directories in an arbitrary order) is told the paths are set.
"""

from __future__ import annotations

import os
import site
import sys
from pathlib import Path

#: Set to the overlay's prefix once its paths are in the environment.
ACTIVE = "TB4_VENV_OVERLAY"
#: The ROS wheels' bootstrapper (ros_wheels_bootstrapper.pth) sets LD_LIBRARY_PATH only while this is unset.
ROS_WHEELS_DONE = "_ROS_WHEELS_BOOTSTRAP_COMPLETE"


def _first(paths: list[str], existing: str) -> str:
    """paths, then the entries of existing that are not among them: one search path, no duplicates."""
    rest = [p for p in dict.fromkeys(existing.split(os.pathsep)) if p and p not in paths]
    return os.pathsep.join(paths + rest)


def activate(base_prefix: str) -> None:
    """Put the base environment under this one (called from this environment's .pth file)."""
    base = Path(base_prefix)
    base_site = base / "lib" / f"python{sys.version_info[0]}.{sys.version_info[1]}" / "site-packages"
    if not base_site.is_dir():
        sys.stderr.write(f"{sys.prefix} overlays {base}, which has no {base_site}: re-run make install-jazzy-wire\n")
        return
    if os.environ.get(ACTIVE) != sys.prefix:
        libraries = [str(Path(sys.prefix) / "lib"), str(base / "lib")]
        libraries += sorted(str(p.resolve()) for p in base_site.glob("ros_*.libs") if p.is_dir())
        env = dict(os.environ)
        env["LD_LIBRARY_PATH"] = _first(libraries, env.get("LD_LIBRARY_PATH", ""))
        env["AMENT_PREFIX_PATH"] = _first([sys.prefix, str(base)], env.get("AMENT_PREFIX_PATH", ""))
        env[ROS_WHEELS_DONE] = "1"
        env[ACTIVE] = sys.prefix
        os.execve(sys.executable, sys.orig_argv, env)
    site.addsitedir(str(base_site))
