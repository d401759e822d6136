"""Print {type name: RIHS01 type hash} of every type of the interface packages the cross-distro stage speaks, as this
environment's rosidl generated them (share/PACKAGE/*/TYPE.json), as JSON."""

from __future__ import annotations

import json
import sys

from tb4.rosenv import share_directories

PACKAGES = (
    "nav2_msgs",
    "irobot_create_msgs",
    "tf2_msgs",
    "geographic_msgs",
    "action_msgs",
    "geometry_msgs",
    "nav_msgs",
    "sensor_msgs",
    "std_msgs",
    "builtin_interfaces",
    "unique_identifier_msgs",
    "lifecycle_msgs",
    "rosgraph_msgs",
)


def main() -> int:
    hashes: dict[str, str] = {}
    for package in PACKAGES:
        # the first share directory that holds the package wins, as for the type support libraries
        folder = next((share / package for share in share_directories() if (share / package).is_dir()), None)
        if folder is None:
            print(f"no {package} in {share_directories()}", file=sys.stderr)
            return 1
        for path in sorted(folder.glob("*/*.json")):
            for entry in json.loads(path.read_text(encoding="utf-8")).get("type_hashes", []):
                hashes.setdefault(entry["type_name"], entry["hash_string"])
    print(json.dumps(hashes, sort_keys=True))
    return 0


if __name__ == "__main__":
    sys.exit(main())
