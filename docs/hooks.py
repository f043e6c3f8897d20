"""mkdocs hooks (mkdocs.yml `hooks:`): fill a page's markers from the code as the site builds.

- `<!-- reference: NAME -->`: a table of docs/gen_reference.py (scenario-keys, cli, channels);
- `<!-- include: PATH -->`: a Markdown file of the repository (an FMU's README), its headings one
  level down and its links to repository files turned into code names;
- `<!-- docstring: PATH -->`: a Python module's docstring, as written;
- `<!-- head: PATH -->`: a C file's opening comment, as written.

So the reference and the model equations are the code's own text, never a copy.
"""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))

import gen_reference  # noqa: E402

ROOT = gen_reference.ROOT
MARKER = re.compile(r"^<!-- (reference|include|docstring|head): (\S+) -->$", re.M)
LINK = re.compile(r"\[([^\]]+)\]\((?!https?:|#)([^)]+)\)")


def _verbatim(text: str) -> str:
    return "```text\n" + text.strip("\n") + "\n```\n"


def _include(path: Path) -> str:
    text = path.read_text()
    text = re.sub(r"^(#+) ", lambda m: "#" + m.group(1) + " ", text, flags=re.M)
    return LINK.sub(lambda m: f"{m.group(1)} (`{m.group(2)}`)", text)


def _docstring(path: Path) -> str:
    return _verbatim(ast.get_docstring(ast.parse(path.read_text()), clean=True) or "")


def _head(path: Path) -> str:
    text = path.read_text()
    comment = text[text.index("/*") + 2:text.index("*/")]
    return _verbatim("\n".join(line.strip()[2:] if line.strip().startswith("* ") else
                               line.strip().lstrip("*") for line in comment.splitlines()))


def expand(markdown: str) -> str:
    def one(match: re.Match) -> str:
        kind, argument = match.groups()
        if kind == "reference":
            return gen_reference.GENERATORS[argument]()
        path = ROOT / argument
        return {"include": _include, "docstring": _docstring, "head": _head}[kind](path)

    return MARKER.sub(one, markdown)


def on_page_markdown(markdown: str, page, config, files) -> str:
    return expand(markdown)
