"""A Ctrl-C or SIGTERM at any moment of `excosim run` ends in one line on stderr and exit status
130 or 143 (orchestrator.cli.signals): while the modules load, while typer parses the command
line, inside the command (its own line: tests/test_cli_conventions.py), and once the command
has ended while the process exits. Before, a stop in the first second or so (and one at the
end) exited silently, or died of the signal, or printed a traceback."""

import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAPER = ROOT / "scenarios" / "paper-2020.toml"
EXCOSIM = Path(sys.executable).with_name("excosim")
ENV = {**os.environ, "OPENBLAS_NUM_THREADS": "1"}

# The program's start as the console script makes it (argv[0] "excosim"), then `body`.
PROGRAM = """
import os, signal, sys
sys.argv[0] = "excosim"
{body}
"""


def program(body: str, *args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", PROGRAM.format(body=body), *args],
                          capture_output=True, text=True, timeout=120, cwd=ROOT, env=ENV)


def one_line(done: subprocess.CompletedProcess, status: int, line: str) -> None:
    assert done.returncode == status, (done.returncode, done.stderr[-500:])
    assert done.stderr == f"excosim: {line}\n", done.stderr[-500:]


@pytest.mark.parametrize("signum, status, stop", [
    (signal.SIGINT, 130, "interrupted"), (signal.SIGTERM, 143, "terminated (SIGTERM)")])
def test_each_phase_says_one_line(signum, status, stop):
    # Starting: the command line's modules are being imported.
    one_line(program(f"import orchestrator.cli\nos.kill(os.getpid(), {int(signum)})\n"
                     "import orchestrator.cli.app\nprint('not reached')"),
             status, f"{stop} while starting; nothing was done")
    # Parsing: typer turns a KeyboardInterrupt into a silent exit 130; main() says it.
    before_run = (f"import orchestrator.cli.run as command\n"
                  f"command.run = lambda *a, **k: os.kill(os.getpid(), {int(signum)})\n"
                  "from orchestrator.cli.app import main\nmain()")
    one_line(program(before_run, "run", str(PAPER), "-q"), status, stop)
    # Exiting: the command has ended and printed what it does; Python runs its exit functions.
    after = (f"import atexit\nimport orchestrator.cli\n"
             f"atexit.register(lambda: os.kill(os.getpid(), {int(signum)}))\n"
             "from orchestrator.cli.app import main\nmain()")
    done = program(after, "--version")
    one_line(done, status, f"{stop} as it exited; the command had ended")
    assert done.stdout.startswith("excosim ")


def test_an_error_a_stop_caused_is_the_stop():
    """A Ctrl-C that cuts an extension module's loading surfaces as "ImportError:
    initialization failed" (raised from the KeyboardInterrupt): one line, 130."""
    body = ("import orchestrator.cli.run as command\n"
            "def run(*a, **k):\n"
            "    try:\n        raise KeyboardInterrupt\n"
            "    except KeyboardInterrupt as error:\n"
            "        raise ImportError('initialization failed') from error\n"
            "command.run = run\nfrom orchestrator.cli.app import main\nmain()")
    one_line(program(body, "run", str(PAPER), "-q"), 130, "interrupted")
    # Not a stop: an error is shown as Python shows it, status 1, and nothing is added.
    body = ("import orchestrator.cli.run as command\n"
            "def run(*a, **k):\n    raise ImportError('a missing module')\n"
            "command.run = run\nfrom orchestrator.cli.app import main\nmain()")
    done = program(body, "run", str(PAPER), "-q")
    assert done.returncode == 1 and "ImportError: a missing module" in done.stderr
    assert "excosim:" not in done.stderr


def test_only_the_program_takes_the_signals_over():
    """Importing the command line (a test, a notebook, a sweep's spawned worker) leaves the
    process's signal handlers as they are."""
    done = subprocess.run([sys.executable, "-c", (
        "import signal, orchestrator.cli.app\n"
        "assert signal.getsignal(signal.SIGTERM) is signal.SIG_DFL\n"
        "assert signal.getsignal(signal.SIGINT) is signal.default_int_handler\n")],
        capture_output=True, text=True, timeout=60, cwd=ROOT)
    assert done.returncode == 0, done.stderr


@pytest.mark.skipif(not EXCOSIM.exists(), reason="no excosim console script next to python")
def test_a_stop_at_any_moment_of_a_run_is_one_line(tmp_path):
    """The console script, stopped at moments from its start to its end: each time either
    the run had ended (status 0, nothing on stderr with -q) or one line and 130/143. The
    first ~30 ms, the interpreter's own start before any code of ours, are not covered."""
    outcomes = []
    for delay in (0.05, 0.1, 0.2, 0.35, 0.5, 0.75, 1.0, 1.5, 2.0, 3.0):
        for signum in (signal.SIGINT, signal.SIGTERM):
            process = subprocess.Popen(
                [str(EXCOSIM), "run", str(PAPER), "--periods", "4", "-q", "-f", "-o",
                 str(tmp_path / "run.mcap")], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                text=True, cwd=tmp_path, env=ENV, start_new_session=True)
            time.sleep(delay)
            try:
                process.send_signal(signum)
            except ProcessLookupError:
                pass
            out, err = process.communicate(timeout=120)
            lines = err.splitlines()
            outcomes.append((delay, signum.name, process.returncode, lines))
            assert "Traceback" not in err, (delay, signum, err)
            if process.returncode == 0:
                assert lines == [], (delay, signum, err)
            else:
                assert process.returncode == 128 + signum and len(lines) == 1, \
                    (delay, signum, process.returncode, err)
                stop = "interrupted" if signum == signal.SIGINT else "terminated (SIGTERM)"
                assert lines[0].startswith(f"excosim: {stop}"), lines
    assert any(status != 0 for _, _, status, _ in outcomes)
    for outcome in outcomes:  # pytest -s: what each moment gave
        print(*outcome)
