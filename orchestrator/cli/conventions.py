"""What every `excosim` command shares with the field's command lines (fmpy, cosim-cli, git):
`-h` and `--help`, help that names values by what they are (`SCENARIO.toml`, `KEY=VALUE`)
rather than by Python type (`<path>`, `<list[str]>`, `<bool>`), a mistake told in one line, and
shell completion.

Typer's help prints the type of every parameter next to the metavar and wraps required
arguments in braces; its usage errors are a boxed panel of several lines. `Command` and `Group`
(given as `cls=` to every command and group) keep typer's parsing and change only those.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import Annotated, Any

import typer
from rich.console import Console
from typer.core import TyperArgument, TyperCommand, TyperGroup, TyperOption

PROG = "excosim"
HELP_OPTIONS = {"help_option_names": ["-h", "--help"]}
SHELLS = ("bash", "zsh", "fish")
COMPLETE_VAR = "_EXCOSIM_COMPLETE"  # the variable the completion scripts set (click's scheme)

_err = Console(stderr=True, highlight=False)


_FAILED = [0]  # lines printed by fail(): main() tells a stop that said nothing from one that did


def fail(message: str) -> None:
    """Print `excosim: message` as one line on stderr (never wrapped into several)."""
    _err.print(f"{PROG}: {message}", markup=False, emoji=False, soft_wrap=True)
    _FAILED[0] += 1


def failures() -> int:
    """How many lines fail() has printed in this process."""
    return _FAILED[0]


class _Argument(TyperArgument):
    """An argument shown by its metavar alone, which already says what the value is."""

    def display_type_rich(self, ctx: Any) -> str | None:
        return None

    def _usage_display_name(self) -> str:
        name = self.display_name_raw if self.required else f"[{self.display_name_raw}]"
        return f"{name}..." if self.nargs != 1 else name


def _plain(params: list[Any]) -> list[Any]:
    for param in params:
        if type(param) is TyperArgument:
            # _Argument adds no state, only display methods: switching the class is safe.
            param.__class__ = _Argument
        elif isinstance(param, TyperOption) and param.is_flag and param.metavar is None:
            param.metavar = ""  # a flag takes no value; typer would show `<bool>`
    return params


def _one_line_main(main: Any, args: Sequence[str] | None, prog_name: str | None,
                   standalone_mode: bool, extra: dict[str, Any]) -> Any:
    """Run typer's main without its standalone handling, which prints usage errors as a panel,
    and end a usage error in one line with its exit status (2)."""
    from typer import Abort, TyperException

    try:
        result = main(args=args, prog_name=prog_name, standalone_mode=False, **extra)
    except TyperException as error:  # click's ClickException and UsageError derive from it
        if not standalone_mode:
            raise
        context = getattr(error, "ctx", None)
        # A group called without a command: its help is the answer. Typer's rich help prints
        # itself while the error is made and leaves the message empty; plain help is the message.
        if type(error).__name__ == "NoArgsIsHelpError":
            if error.format_message().strip():
                print(error.format_message())
            sys.exit(0)
        message = " ".join(error.format_message().split()).rstrip(".")
        message = message[:1].lower() + message[1:]  # like our own messages: "no such option"
        where = context.command_path if context is not None else PROG
        fail(f"{message} (see '{where} -h')" if error.exit_code == 2 else message)
        sys.exit(error.exit_code)
    except Abort:
        if not standalone_mode:
            raise
        fail("aborted")
        sys.exit(1)
    if not standalone_mode:
        return result
    # Without standalone handling typer returns the status of a typer.Exit (None otherwise).
    sys.exit(result if isinstance(result, int) else 0)


class Command(TyperCommand):
    """A typer command with plain help and one-line usage errors."""

    def get_params(self, ctx: Any) -> list[Any]:
        return _plain(super().get_params(ctx))


class Group(TyperGroup):
    """A typer group with plain help and one-line usage errors (for the whole command line:
    the root group's main runs every subcommand)."""

    def get_params(self, ctx: Any) -> list[Any]:
        return _plain(super().get_params(ctx))

    def main(self, args: Sequence[str] | None = None, prog_name: str | None = None,
             complete_var: str | None = None, standalone_mode: bool = True,
             **extra: Any) -> Any:
        def typer_main(**kwargs: Any) -> Any:
            return super(Group, self).main(complete_var=complete_var, **kwargs)

        return _one_line_main(typer_main, args, prog_name, standalone_mode, extra)


def count(n: int, noun: str, nouns: str | None = None) -> str:
    """`1 period`, `3 periods`: a number and its noun in the right number."""
    return f"{n} {noun if n == 1 else (nouns or noun + 's')}"


def version() -> str:
    """The installed excosim's version (package metadata), or "unknown" outside an install."""
    from importlib.metadata import PackageNotFoundError
    from importlib.metadata import version as installed

    try:
        return installed("excosim")
    except PackageNotFoundError:
        return "unknown"


def completion_script(shell: str) -> str:
    """The script that makes `shell` complete excosim's commands, options and files: it asks
    `excosim` itself (with COMPLETE_VAR set) what fits the words typed so far."""
    from typer.completion import completion_init, get_completion_script

    completion_init()
    return get_completion_script(prog_name=PROG, complete_var=COMPLETE_VAR, shell=shell)


def enable_completion() -> None:
    """Register typer's completion classes, which answer the scripts' requests (click's own
    would expect another request format)."""
    from typer.completion import completion_init

    completion_init()


def json_text(data: Any) -> str:
    """JSON of plain data with every NaN or infinity as null: a bare NaN is not JSON, and a
    damaged or foreign log may hold one."""
    import json
    import math

    def clean(value: Any) -> Any:
        if isinstance(value, float) and not math.isfinite(value):
            return None
        if isinstance(value, dict):
            return {key: clean(item) for key, item in value.items()}
        if isinstance(value, list | tuple):
            return [clean(item) for item in value]
        return value

    return json.dumps(clean(data), allow_nan=False)


def completion(
    shell: Annotated[str, typer.Argument(metavar="SHELL", help=f"One of {', '.join(SHELLS)}.")],
) -> None:
    """Print the completion script of a shell (bash, zsh, fish).

    Put `eval "$(excosim completion bash)"` in ~/.bashrc (zsh: the same in ~/.zshrc; fish:
    `excosim completion fish | source` in ~/.config/fish/config.fish).
    """
    if shell not in SHELLS:
        fail(f"completion: unknown shell {shell!r}; known: {', '.join(SHELLS)}")
        raise typer.Exit(2)
    print(completion_script(shell))


def status_on_terminal(quiet: bool) -> None:
    """Say on stderr, when it is a terminal and not `quiet`, what takes a while before a run
    starts (a substitute FMU's identification: orchestrator.plants.servo_setup)."""
    if quiet or not sys.stderr.isatty():
        return
    from orchestrator.plants import servo_setup

    servo_setup.on_identify = lambda line: print(line, file=sys.stderr, flush=True)
