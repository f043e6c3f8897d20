"""`python -m fmus build` builds every FMU; `python -m fmus demo` simulates each one briefly."""

from __future__ import annotations

import sys

from fmus.builder import BuildError, build, model_names
from fmus.demo import demo

USAGE = "usage: python -m fmus {build|demo}"


def main(argv: list[str] | None = None) -> int:
    """Run the command in argv; return the process exit status (0 ok, 1 failed, 2 usage)."""
    args = sys.argv[1:] if argv is None else argv
    if len(args) != 1 or args[0] not in ("build", "demo"):
        print(USAGE, file=sys.stderr)
        return 2
    if args[0] == "demo":
        try:
            print(demo())
        except BuildError as exc:
            print(f"error: {exc}", file=sys.stderr)
            return 1
        return 0
    failed = 0
    for name in model_names():  # build the rest even when one model fails
        try:
            print(f"{name}: {build(name)}")
        except BuildError as exc:
            print(f"error: {exc}", file=sys.stderr)
            failed += 1
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
