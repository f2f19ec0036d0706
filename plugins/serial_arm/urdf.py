"""Where a description's `urdf:` points: a file relative to the description, or a robot of the offline
package `example-robot-data` (`example-robot-data:ur10`, or a path inside its `robots/` folder)."""

from __future__ import annotations

import xml.etree.ElementTree as ET
from importlib import metadata
from pathlib import Path

PACKAGE = "example-robot-data"
PREFIX = PACKAGE + ":"
# short names of the arms in example-robot-data (paths inside its robots/ folder)
SHORT_NAMES = {
    "ur3": "ur_description/urdf/ur3_robot.urdf",
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "ur10": "ur_description/urdf/ur10_robot.urdf",
    "panda": "panda_description/urdf/panda.urdf",
}


def robots_folder() -> Path:
    """The robots/ folder of the installed example-robot-data (its files live in the cmeel prefix)."""
    try:
        dist = metadata.distribution(PACKAGE)
    except metadata.PackageNotFoundError:
        raise FileNotFoundError(f"the package {PACKAGE} is not installed (pip install {PACKAGE})") from None
    return Path(str(dist.locate_file("cmeel.prefix/share/example-robot-data/robots")))


def urdf_path(value: str, base: Path) -> Path:
    """The URDF file `value` names; `base` is the folder of the description. FileNotFoundError says
    what was looked for."""
    if value.startswith(PREFIX):
        name = value[len(PREFIX):]
        file = robots_folder() / SHORT_NAMES.get(name, name)
        if not file.is_file():
            raise FileNotFoundError(f"{PACKAGE} has no robot {name!r} ({file} does not exist); short names: "
                                    f"{', '.join(SHORT_NAMES)}, or a path inside {robots_folder()}")
        return file
    file = Path(value) if Path(value).is_absolute() else base / value
    if not file.is_file():
        raise FileNotFoundError(f"URDF file not found: {file}")
    return file


def root_link(robot: ET.Element) -> str:
    """The name of the root link of a parsed URDF `<robot>`: the one link no joint has as its child."""
    children = {j.find("child").get("link") for j in robot.findall("joint")}
    return next(link.get("name") for link in robot.findall("link") if link.get("name") not in children)
