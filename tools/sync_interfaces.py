"""Write our interface packages' definition files from a reference document, byte for byte.

The reference (``shared/reference/interfaces-full.md`` and its kind) holds each upstream file as a
``## pkg/kind/Name.ext`` heading followed by a fenced block. Running this makes ``interfaces/`` match it exactly;
the interface test checks the built types against the same document, so the two cannot drift apart unnoticed.

    python tools/sync_interfaces.py ../shared/reference/interfaces-full.md [--root interfaces]
"""

from __future__ import annotations

import argparse
import pathlib
import re
import sys

HEADING = re.compile(r"^## ([a-z0-9_]+)/(msg|srv|action)/([A-Za-z0-9]+)\.(msg|srv|action)\s*$")


def parse_reference(text: str) -> dict[str, str]:
    """Map 'pkg/kind/Name.ext' to the file's text, for every definition in a reference document."""
    definitions: dict[str, str] = {}
    lines = text.splitlines()
    i = 0
    while i < len(lines):
        match = HEADING.match(lines[i])
        if not match:
            i += 1
            continue
        pkg, kind, name, ext = match.groups()
        j = i + 1
        while j < len(lines) and not lines[j].startswith("```"):
            j += 1
        k = j + 1
        while k < len(lines) and not lines[k].startswith("```") and not lines[k].endswith("```"):
            k += 1
        if k >= len(lines):
            raise ValueError(f"line {i + 1}: the block of {pkg}/{kind}/{name}.{ext} is not closed")
        body = "\n".join(lines[j + 1 : k]) + "\n"
        if not lines[k].startswith("```"):  # upstream's file has no final newline: the fence follows its last line
            body += lines[k][: -len("```")]
        definitions[f"{pkg}/{kind}/{name}.{ext}"] = body
        i = k + 1
    return definitions


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("reference", type=pathlib.Path)
    parser.add_argument("--root", type=pathlib.Path, default=pathlib.Path(__file__).resolve().parents[1] / "interfaces")
    parser.add_argument("--package", action="append", help="only these packages (default: all in the document)")
    args = parser.parse_args(argv)
    definitions = parse_reference(args.reference.read_text())
    written = 0
    for rel, body in sorted(definitions.items()):
        pkg = rel.split("/", 1)[0]
        if args.package and pkg not in args.package:
            continue
        path = args.root / rel
        path.parent.mkdir(parents=True, exist_ok=True)
        if not path.exists() or path.read_text() != body:
            path.write_text(body)
            written += 1
    print(f"{len(definitions)} definitions in {args.reference}; {written} file(s) written under {args.root}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
