"""Speed/accuracy frontier of every visibility method (a thin entry point to ``warpshade bench``).

What it shows: per method configuration and SH order, time per frame, memory, transfer and radiance
error against a cached ray-traced ground truth (see ``warpshade/bench/runner.py``).
Success criteria: every configuration measured (no ``failed`` records), finite errors.
How to run::

    python benchmarks/frontier.py [--quick] [--out DIR] [--json PATH] [any warpshade bench flag]

Prints the table; ``--json PATH`` copies ``results.json`` there. Medians of repeats after warm-up,
compilation excluded; numbers from a shared, loaded machine.
"""

from __future__ import annotations

import os
import shutil
import sys
import tempfile


def main(argv=None) -> int:
    argv = list(sys.argv[1:] if argv is None else argv)
    json_path = None
    if "--json" in argv:
        k = argv.index("--json")
        json_path = argv[k + 1]
        del argv[k:k + 2]
    if "--out" not in argv:
        argv += ["--out", tempfile.mkdtemp(prefix="warpshade-frontier-")]
    out = argv[argv.index("--out") + 1]
    from warpshade.cli import main as cli_main

    rc = cli_main(["bench", *argv])
    if rc == 0 and json_path:
        shutil.copyfile(os.path.join(out, "results.json"), json_path)
    return rc


if __name__ == "__main__":
    raise SystemExit(main())
