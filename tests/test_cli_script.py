"""The ``stochmod`` console script (:func:`stochmod.cli.script`): main's output and exit code,
then an exit without the interpreter's teardown."""

from __future__ import annotations

import subprocess
import sys

from stochmod.cli import main

_SCRIPT = ("import atexit, sys\n"
           "atexit.register(lambda: sys.stdout.write('<teardown>'))\n"
           "from stochmod.cli import script\n"
           "script()\n")


def _script(*argv: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", _SCRIPT, *argv], check=False,
                          capture_output=True, text=True, timeout=300)


def test_script_prints_what_main_prints_and_skips_the_teardown(capsys):
    assert main(["processes"]) == 0
    expected = capsys.readouterr().out
    done = _script("processes")
    assert done.returncode == 0
    # the whole output (a pipe: block-buffered, flushed before the exit), and no teardown:
    # a normal exit would run the atexit handler
    assert done.stdout == expected and len(expected) > 1000


def test_script_returns_main_s_error_code_with_the_message(tmp_path):
    missing = tmp_path / "missing.npz"
    assert main(["calibrate", str(missing), "--out", str(tmp_path / "a")]) == 2
    done = _script("calibrate", str(missing), "--out", str(tmp_path / "b"))
    assert done.returncode == 2 and done.stdout == ""
    assert done.stderr.startswith("stochmod calibrate: error: ") and str(missing) in done.stderr
