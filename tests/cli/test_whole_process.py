"""The console script's garbage collector (:func:`warpshade.cli.main` with ``whole_process``, :func:`warpshade.cli.entry`):
what the command line imported is frozen (:func:`gc.freeze`) in a process that exists for the command, and in no other;
the process still exits as usual (its output flushed, its exit code kept)."""

from __future__ import annotations

import gc
import os
import subprocess
import sys

from helpers import REPO
from warpshade.cli import main

ENV = dict(os.environ, PYTHONPATH=REPO + os.pathsep + os.environ.get("PYTHONPATH", ""))


def test_a_call_from_a_longer_lived_process_freezes_nothing(capsys):
    before = gc.get_freeze_count()
    assert main(["info"]) == 0
    assert gc.get_freeze_count() == before


def test_a_whole_process_freezes_what_the_command_line_imported():
    code = ("import gc\n"
            "from warpshade.cli import main\n"
            "before = gc.get_freeze_count()\n"
            "code = main(['info'], whole_process=True)\n"
            "print(code, before, gc.get_freeze_count())\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=ENV, timeout=120)
    assert out.returncode == 0, out.stderr
    code, before, after = (int(w) for w in out.stdout.splitlines()[-1].split())
    # Warp, NumPy, SciPy and every subcommand's module are imported by then: far more than 10^4 tracked objects
    assert code == 0 and before == 0 and after > 10_000


def test_the_console_script_still_flushes_its_output_and_keeps_its_exit_code():
    ok = subprocess.run([sys.executable, "-m", "warpshade", "info"], capture_output=True, text=True, env=ENV, timeout=120)
    assert ok.returncode == 0, ok.stderr
    assert ok.stdout.splitlines()[-1].split()[0] == "cache"  # the last line info prints, there when piped
    bad = subprocess.run([sys.executable, "-m", "warpshade", "run", "no_such_scene.usda", "--workers", "0"],
                         capture_output=True, text=True, env=ENV, timeout=120)
    assert bad.returncode == 1 and "error" in bad.stderr
