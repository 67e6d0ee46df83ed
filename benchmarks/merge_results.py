"""Merge a partial re-measurement into the committed full sweep.

`warpshade bench` writes a whole results directory; re-running the full five-mesh sweep takes a
long time, so when one method changes only its records are re-measured
(``python -m warpshade bench --out NEW --methods M --meshes ... --ground-truth-rays 4096 --repeat 3``)
and merged here: every (method, mesh) pair present in ``NEW/results.json`` replaces that pair's
records in ``--into`` (in place of the old block, else appended), the Pareto flags are recomputed
over the merged set, and ``results.json``, ``results.csv``, ``results.md`` (its header paragraph kept,
``--note`` appended), ``pareto.png`` and the planner frontier are rewritten from the merged records.
Every other record is kept as measured.

Usage::

    python benchmarks/merge_results.py NEW/results.json --note "hemiraster rows re-measured on DATE"
"""

from __future__ import annotations

import argparse
import json
import os
import sys


def merge_records(old: list[dict], new: list[dict]) -> list[dict]:
    """``old`` with each (method, mesh) pair of ``new`` replaced by ``new``'s records for it."""
    pairs = {(r["method"], r["mesh"]) for r in new}
    merged, placed = [], set()
    for r in old:
        key = (r["method"], r["mesh"])
        if key in pairs:
            if key not in placed:  # the new block goes where the old one was
                merged += [n for n in new if (n["method"], n["mesh"]) == key]
                placed.add(key)
            continue
        merged.append(r)
    merged += [n for n in new if (n["method"], n["mesh"]) not in placed]
    return merged


def main(argv=None) -> int:
    from warpshade.bench.report import frontier_from_results, markdown_table, plot_pareto, write_csv, write_json
    from warpshade.bench.runner import mark_pareto

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("new", help="results.json of the partial re-measurement")
    ap.add_argument("--into", default="benchmarks/results", help="committed results directory")
    ap.add_argument("--frontier", default="warpshade/data/frontier.json", help="planner frontier to rewrite")
    ap.add_argument("--note", default="", help="appended to results.md's header and the frontier's machine note")
    args = ap.parse_args(argv)

    with open(os.path.join(args.into, "results.json")) as f:
        old = json.load(f)
    with open(args.new) as f:
        new = json.load(f)
    md_path = os.path.join(args.into, "results.md")
    with open(md_path) as f:
        md = f.read()
    body = markdown_table(old)  # the committed table, rendered before the flags are recomputed
    if body not in md:
        print(f"merge_results: {md_path} does not hold the table of {args.into}/results.json", file=sys.stderr)
        return 1
    start = md.index(body)
    merged = merge_records(old, new)
    mark_pareto(merged)
    write_json(os.path.join(args.into, "results.json"), merged)
    write_csv(os.path.join(args.into, "results.csv"), merged)
    header = md[:start].rstrip("\n")
    if args.note:
        header += " " + args.note
    with open(md_path, "w") as f:
        f.write(header + "\n\n" + markdown_table(merged) + md[start + len(body):])
    with open(args.frontier) as f:
        machine = json.load(f).get("machine", "")
    if args.note:
        machine += "; " + args.note
    write_json(args.frontier, {**frontier_from_results(merged), "machine": machine}, indent=2)
    plot_pareto(os.path.join(args.into, "pareto.png"), merged, title=machine)
    print(f"merge_results: {len(old)} -> {len(merged)} records; replaced {len({(r['method'], r['mesh']) for r in new})} "
          f"(method, mesh) blocks with {len(new)} records")
    return 0


if __name__ == "__main__":
    sys.exit(main())
