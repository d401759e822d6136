"""Every interface we build is upstream's, field for field: checked on the built Python types, not on our files.

The references (tests/data/reference/, copies of shared/reference/: interfaces-full.md holds Nav2 Kilted's nav2_msgs,
geographic_msgs and irobot_create_msgs; interfaces-jazzy-nav2.md holds Nav2 Jazzy's nav2_msgs, verbatim) are parsed
here with a small .msg reader of our own, and each definition is compared with what rosidl generated: field names and
order, types (with bounds and array sizes), default values and constants. The installed nav2_msgs is checked against
the reference of the wire format it was built for (TB4_ROS_DISTRO), and must be exactly one of the two.
"""

from __future__ import annotations

import importlib
import importlib.util
import math
import pathlib
import re

import pytest

from tool_modules import load_tool

ROOT = pathlib.Path(__file__).resolve().parents[2]
REFERENCES = ROOT / "tests" / "data" / "reference"

sync_interfaces = load_tool("sync_interfaces")

KILTED: dict[str, str] = sync_interfaces.parse_reference((REFERENCES / "interfaces-full.md").read_text())
JAZZY_NAV2: dict[str, str] = sync_interfaces.parse_reference((REFERENCES / "interfaces-jazzy-nav2.md").read_text())


def _installed_wire_format() -> str:
    from tb4.wire import wire_format

    return wire_format()


WIRE_FORMAT = _installed_wire_format()
#: What the installed packages must match: Kilted's everything, or Jazzy's nav2_msgs with the rest unchanged.
DEFINITIONS: dict[str, str] = (
    KILTED
    if WIRE_FORMAT == "kilted"
    else {**{k: v for k, v in KILTED.items() if not k.startswith("nav2_msgs/")}, **JAZZY_NAV2}
)
#: Where each definition's source file lives in interfaces/.
SOURCE_DIRS = {"kilted": "interfaces", "jazzy": "interfaces/jazzy"}

# .msg primitive names -> the names rosidl's Python types report.
PRIMITIVES = {
    "bool": "boolean",
    "byte": "octet",
    "char": "uint8",
    "float32": "float",
    "float64": "double",
    "int8": "int8",
    "uint8": "uint8",
    "int16": "int16",
    "uint16": "uint16",
    "int32": "int32",
    "uint32": "uint32",
    "int64": "int64",
    "uint64": "uint64",
    "string": "string",
    "wstring": "wstring",
}
FIELD = re.compile(
    r"^(?P<type>[A-Za-z0-9_/]+(?:<=\d+)?)(?P<array>\[(?:<=)?\d*\])?\s+(?P<name>[A-Za-z0-9_]+)(?P<rest>.*)$"
)


def _strip_comment(line: str) -> str:
    """Drop a trailing comment, but not a '#' inside a quoted default."""
    quote = None
    for i, ch in enumerate(line):
        if ch in "'\"":
            quote = None if quote == ch else (quote or ch)
        elif ch == "#" and quote is None:
            return line[:i]
    return line


def _base_type(raw: str, package: str) -> str:
    if raw.startswith("string<="):
        return f"string<{raw[len('string<=') :]}>"
    if raw in PRIMITIVES:
        return PRIMITIVES[raw]
    if raw == "Header":
        return "std_msgs/Header"
    return raw if "/" in raw else f"{package}/{raw}"


def _type_string(raw: str, array: str | None, package: str) -> str:
    base = _base_type(raw, package)
    if not array:
        return base
    inside = array[1:-1]
    if inside == "":
        return f"sequence<{base}>"
    if inside.startswith("<="):
        return f"sequence<{base}, {inside[2:]}>"
    return f"{base}[{inside}]"


def parse_section(text: str, package: str) -> tuple[list[tuple[str, str, str | None]], dict[str, str]]:
    """Fields (name, rosidl type string, default text) and constants (name -> value text) of one .msg section."""
    fields: list[tuple[str, str, str | None]] = []
    constants: dict[str, str] = {}
    for line in text.splitlines():
        line = _strip_comment(line).strip()
        if not line:
            continue
        match = FIELD.match(line)
        assert match, f"cannot read definition line {line!r}"
        rest = match["rest"].strip()
        if rest.startswith("="):
            constants[match["name"]] = rest[1:].strip()
            continue
        fields.append((match["name"], _type_string(match["type"], match["array"], package), rest or None))
    return fields, constants


def _classes(rel: str) -> list[tuple[type, str]]:
    package, kind, filename = rel.split("/")
    name = filename.rsplit(".", 1)[0]
    module = importlib.import_module(f"{package}.{kind}")
    top = getattr(module, name)
    sections = DEFINITIONS[rel].split("\n---\n") if kind != "msg" else [DEFINITIONS[rel]]
    if kind == "msg":
        return [(top, sections[0])]
    parts = ("Request", "Response") if kind == "srv" else ("Goal", "Result", "Feedback")
    assert len(sections) == len(parts), f"{rel}: {len(sections)} sections"
    return [(getattr(top, part), section) for part, section in zip(parts, sections, strict=True)]


def _same_value(actual: object, expected_text: str, type_string: str) -> bool:
    text = expected_text.strip()
    if type_string == "boolean":
        return actual is (text.lower() in ("true", "1"))
    if type_string.startswith("string") or type_string == "wstring":
        return actual == (text[1:-1] if text[:1] in "'\"" else text)
    if "[" in type_string or type_string.startswith("sequence"):
        expected = [float(v) for v in text.strip("[]").split(",") if v.strip()]
        return [float(v) for v in actual] == expected  # type: ignore[attr-defined]
    if type_string in ("float", "double"):
        return math.isclose(float(actual), float(text), rel_tol=1e-6)  # type: ignore[arg-type]
    return int(actual) == int(text, 0)  # type: ignore[call-overload]


def test_the_references_hold_every_definition() -> None:
    counts = {p: sum(rel.startswith(p + "/") for rel in KILTED) for p in {rel.split("/")[0] for rel in KILTED}}
    assert counts == {"nav2_msgs": 51, "geographic_msgs": 20, "irobot_create_msgs": 31}
    assert {rel.split("/")[0] for rel in JAZZY_NAV2} == {"nav2_msgs"} and len(JAZZY_NAV2) == 51


@pytest.mark.parametrize("rel", sorted(KILTED))
def test_our_kilted_file_is_upstreams(rel: str) -> None:
    """The files we build from are the reference's text, byte for byte."""
    assert (ROOT / "interfaces" / rel).read_text() == KILTED[rel]


@pytest.mark.parametrize("rel", sorted(JAZZY_NAV2))
def test_our_jazzy_file_is_upstreams(rel: str) -> None:
    assert (ROOT / "interfaces" / "jazzy" / rel).read_text() == JAZZY_NAV2[rel]


def test_only_the_references_definitions_are_built() -> None:
    """No extra definition file hides in a package we build (it would be on the wire with no upstream twin)."""
    for root, reference in ((ROOT / "interfaces", KILTED), (ROOT / "interfaces" / "jazzy", JAZZY_NAV2)):
        packages = {rel.split("/")[0] for rel in reference}
        files = {
            str(path.relative_to(root))
            for package in packages
            for path in (root / package).rglob("*")
            if path.suffix in (".msg", ".srv", ".action")
        }
        assert files == set(reference)


@pytest.mark.parametrize("rel", sorted(DEFINITIONS))
def test_built_type_matches_the_reference(rel: str) -> None:
    package = rel.split("/")[0]
    for cls, section in _classes(rel):
        fields, constants = parse_section(section, package)
        built = cls.get_fields_and_field_types()
        assert list(built) == [name for name, _, _ in fields], f"{cls.__name__}: field names or order differ"
        for name, type_string, _ in fields:
            assert built[name] == type_string, f"{cls.__name__}.{name}: built {built[name]}, upstream {type_string}"
        instance = cls()
        for name, type_string, default in fields:
            if default is not None:
                value = getattr(instance, name)
                assert _same_value(value, default, type_string), f"{cls.__name__}.{name} default {value!r} != {default}"
        for name, value_text in constants.items():
            assert hasattr(cls, name), f"{cls.__name__} lacks constant {name}"
            value = getattr(cls, name)
            if isinstance(value, str):
                assert value == value_text.strip("'\""), f"{cls.__name__}.{name}"
            elif isinstance(value, float):
                assert math.isclose(value, float(value_text)), f"{cls.__name__}.{name}"
            else:
                assert value == int(value_text, 0), f"{cls.__name__}.{name} = {value}, upstream {value_text}"
