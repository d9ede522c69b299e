"""``python -m bench [NAME [ARGS...]]`` (what ``./dev bench`` runs): run the entry script
bench/NAME.py as ``python -m bench.NAME ARGS...``; with no NAME, or one that is not an
entry script, list them (with the first sentence of each one's docstring) and exit 2."""

from __future__ import annotations

import ast
import os
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent


def entry_scripts() -> dict[str, str]:
    """Every entry script's name and the first sentence of its docstring (read, not
    imported: listing them imports nothing heavy)."""
    out = {}
    for f in sorted(HERE.glob("*.py")):
        if f.name.startswith("_"):
            continue
        doc = ast.get_docstring(ast.parse(f.read_text(), str(f))) or ""
        first = " ".join(doc.strip().split("\n\n", 1)[0].split())  # the first paragraph
        first = first.split(". ", 1)[0].rstrip(".")  # its first sentence
        out[f.stem] = first if len(first) <= 90 else first[:87] + "..."
    return out


def main(argv: list[str]) -> int:
    scripts = entry_scripts()
    if not argv or argv[0] not in scripts:
        if argv and argv[0] not in ("-h", "--help"):
            print(f"bench: no entry script named {argv[0]!r}", file=sys.stderr)
        print("usage: ./dev bench NAME [ARGS...]   (python -m bench.NAME ARGS...)\n"
              "entry scripts (bench/NAME.py; ./dev bench NAME --help for its options):",
              file=sys.stderr)
        width = max(map(len, scripts))
        for name, line in scripts.items():
            print(f"  {name:<{width}}  {line}", file=sys.stderr)
        return 0 if argv[:1] in (["-h"], ["--help"]) else 2
    # the script runs as its own __main__ (its forked pools look their tasks up there)
    os.execv(sys.executable, [sys.executable, "-m", f"bench.{argv[0]}", *argv[1:]])
    return 1  # not reached


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
