"""Benchmark outputs: ``results.json``, ``results.csv``, ``pareto.png``, a text table, a Markdown table (``results.md``) and
the planner's frontier file."""

from __future__ import annotations

import csv
import json

import numpy as np

from .._atomic import replace_atomically
CSV_COLUMNS = ["method", "mesh", "quantity", "vertices", "triangles", "order", "knobs", "seconds", "repeat", "build_seconds",
               "error_mean", "error_p95", "error_max", "radiance_error_sky", "radiance_error_studio",
               "peak_rss_bytes", "array_bytes", "pareto", "finite", "failed"]


def _atomic_write(path: str, write) -> None:
    """Call ``write(f)`` on a text file opened under a temporary name, then rename it onto ``path``."""
    def _text(tmp):
        with open(tmp, "w", newline="") as f:
            write(f)
    replace_atomically(_text, path)


def write_json(path: str, data, indent: int = 1) -> None:
    """JSON written atomically (temporary file, then rename): ``results.json`` (the list of records,
    ``indent=1``), the frontier file and the CLI's ``--json`` outputs (``indent=2``). NumPy scalars
    and arrays are written as numbers and lists."""
    _atomic_write(path, lambda f: json.dump(data, f, indent=indent, default=_jsonable))


def _jsonable(x):
    if isinstance(x, np.generic):
        return x.item()
    if isinstance(x, np.ndarray):
        return x.tolist()
    return str(x)


def write_csv(path: str, records: list[dict]) -> None:
    """``results.csv``: one row per record; ``knobs`` as compact JSON."""
    def write(f):
        w = csv.DictWriter(f, fieldnames=CSV_COLUMNS, extrasaction="ignore")
        w.writeheader()
        for r in records:
            row = dict(r)
            row["knobs"] = json.dumps(r.get("knobs", {}), sort_keys=True, default=_jsonable)
            row.setdefault("quantity", "transfer")
            w.writerow(row)
    _atomic_write(path, write)


def label(r: dict) -> str:
    """Short configuration label: order and the knobs that are not seeds."""
    knobs = " ".join(f"{k}={v}" for k, v in sorted(r.get("knobs", {}).items()) if k != "seed")
    return knobs if is_area(r) else f"o{r['order']} {knobs}".strip()


def is_area(r: dict) -> bool:
    """An area-light visibility record (GEARS or its ray-traced comparison; see :mod:`.area`)."""
    return r.get("quantity") == "area_visibility"


def _fmt(x, spec: str, width: int) -> str:
    return f"{'-':>{width}}" if x is None else f"{x:>{width}{spec}}"


def format_table(records: list[dict]) -> str:
    """Plain-text table, one line per record, grouped by mesh (what ``warpshade bench`` prints)."""
    lines = [f"{'mesh':<12}{'method':<12}{'config':<44}{'ms/frame':>10}{'err mean':>10}{'err p95':>9}"
             f"{'rad sky':>9}{'rad stu':>9}{'peak MB':>9}{'arr MB':>8}  P"]
    for r in records:
        if "failed" in r:
            lines.append(f"{r['mesh']:<12}{r['method']:<12}{label(r):<44} FAILED: {r['failed']}")
            continue
        peak = "-" if r.get("peak_rss_bytes") is None else f"{r['peak_rss_bytes'] / 2**20:.1f}"
        arr = None if r.get("array_bytes") is None else r["array_bytes"] / 2**20
        lines.append(f"{r['mesh']:<12}{r['method']:<12}{label(r)[:43]:<44}{r['seconds'] * 1e3:>10.2f}"
                     f"{r['error_mean']:>10.4f}{r['error_p95']:>9.4f}{_fmt(r.get('radiance_error_sky'), '.4f', 9)}"
                     f"{_fmt(r.get('radiance_error_studio'), '.4f', 9)}{peak:>9}{_fmt(arr, '.2f', 8)}"
                     f"  {'*' if r.get('pareto') else ''}")
    if any(is_area(r) for r in records):
        lines.append("gears / area-rays rows: error = absolute visible fraction of the rect light |V - V*| "
                     "(not transfer error), truth: 32x32 jittered rays per vertex")
    return "\n".join(lines)


def markdown_table(records: list[dict]) -> str:
    """Markdown table of ``results.md`` (Pareto-optimal configurations marked ★)."""
    out = ["| mesh | method | config | ms/frame | error mean | error p95 | radiance err sky / studio | peak RSS MB | arrays MB |",
           "| --- | --- | --- | ---: | ---: | ---: | ---: | ---: | ---: |"]
    for r in records:
        if "failed" in r:
            out.append(f"| {r['mesh']} | {r['method']} | {label(r)} | failed: {r['failed']} | | | | | |")
            continue
        peak = "-" if r.get("peak_rss_bytes") is None else f"{r['peak_rss_bytes'] / 2**20:.1f}"
        star = " ★" if r.get("pareto") else ""
        if is_area(r):
            out.append(f"| {r['mesh']} | {r['method']} | `{label(r)}`{star} | {r['seconds'] * 1e3:.2f} | "
                       f"{r['error_mean']:.4f} ‡ | {r['error_p95']:.4f} ‡ | - | {peak} | - |")
            continue
        out.append(f"| {r['mesh']} | {r['method']} | `{label(r)}`{star} | {r['seconds'] * 1e3:.2f} | "
                   f"{r['error_mean']:.4f} | {r['error_p95']:.4f} | "
                   f"{r['radiance_error_sky']:.4f} / {r['radiance_error_studio']:.4f} | {peak} | "
                   f"{r['array_bytes'] / 2**20:.2f} |")
    if any(is_area(r) for r in records):
        out.append("\n‡ gears / area-rays: absolute error of the visible fraction of a rect light (docs/conventions.md §4) "
                   "against 32×32 jittered shadow rays per vertex, not the transfer error.")
    return "\n".join(out)


def plot_pareto(path: str, records: list[dict], title: str = "") -> None:
    """``pareto.png``: per mesh, time per frame against mean transfer error (log–log) at the default SH
    order 5: one curve per method (its own frontier as a line, dominated configurations as faint points),
    the frontier over all methods as a black dashed step line. Other orders are not on the same error
    scale (fewer coefficients) and are left to the table."""
    import textwrap

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .records import pareto_mask
    from .runner import DEFAULT_ORDER

    ok = [r for r in records if "failed" not in r and r["order"] == DEFAULT_ORDER and not is_area(r)]
    area = [r for r in records if "failed" not in r and is_area(r)]
    meshes = list(dict.fromkeys(r["mesh"] for r in ok))
    methods = list(dict.fromkeys(r["method"] for r in ok))
    panels = len(meshes) + (1 if area else 0)
    cols = min(3, max(1, panels))
    rows = (panels + cols - 1) // cols
    fig, axes = plt.subplots(rows, cols, figsize=(5.2 * cols, 4.2 * rows), squeeze=False)
    colors = {m: plt.get_cmap("tab10")(i % 10) for i, m in enumerate(methods)}
    for ax, mesh in zip(axes.ravel(), meshes):
        recs = [r for r in ok if r["mesh"] == mesh]
        for m in methods:
            mr = [r for r in recs if r["method"] == m]
            if not mr:
                continue
            s = np.array([r["seconds"] for r in mr])
            e = np.maximum(np.array([r["error_mean"] for r in mr]), 1e-6)
            own = pareto_mask(s, e)
            ax.scatter(s[~own], e[~own], color=colors[m], alpha=0.35, s=14)
            order = np.argsort(s[own])
            ax.plot(s[own][order], e[own][order], "o-", color=colors[m], label=m, ms=4)
        s = np.array([r["seconds"] for r in recs])
        e = np.maximum(np.array([r["error_mean"] for r in recs]), 1e-6)
        front = pareto_mask(s, e)
        o = np.argsort(s[front])
        ax.step(s[front][o], e[front][o], "k--", where="post", lw=1, label="frontier")
        ax.scatter(s[front], e[front], facecolors="none", edgecolors="k", s=60, lw=1)
        ax.set_xscale("log")
        ax.set_yscale("log")
        v = recs[0]["vertices"]
        ax.set_title(f"{mesh} ({v} vertices)")
        ax.set_xlabel("transfer time per frame [s]")
        ax.set_ylabel("mean relative L2 transfer error")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    if area:
        _plot_area(axes.ravel()[len(meshes)], area, plt)
    for ax in axes.ravel()[panels:]:
        ax.axis("off")
    if title:
        fig.suptitle("\n".join(textwrap.wrap(title, 40 * cols)), fontsize=8)
    fig.tight_layout()
    try:
        replace_atomically(lambda tmp: fig.savefig(tmp, dpi=110), path)
    finally:
        plt.close(fig)


def _plot_area(ax, area: list[dict], plt) -> None:
    """The area-light panel: GEARS (solid, one curve per mesh along k) and the ray tracer at equal k
    (dashed); y is the mean absolute visible-fraction error, another quantity than the transfer panels."""
    meshes = list(dict.fromkeys(r["mesh"] for r in area))
    colors = {m: plt.get_cmap("Dark2")(i % 8) for i, m in enumerate(meshes)}
    for mesh in meshes:
        for method, style in (("gears", "o-"), ("area-rays", "s--")):
            mr = sorted((r for r in area if r["mesh"] == mesh and r["method"] == method
                         and (method == "area-rays" or r["knobs"].get("grid") == 16)), key=lambda r: r["knobs"]["k"])
            if not mr:
                continue
            s = [r["seconds"] for r in mr]
            e = [max(r["error_mean"], 1e-6) for r in mr]
            ax.plot(s, e, style, color=colors[mesh], ms=4, label=f"{method} {mesh}")
            for r, x, y in zip(mr, s, e):
                ax.annotate(f"k{r['knobs']['k']}", (x, y), fontsize=6, xytext=(2, 2), textcoords="offset points")
        other = [r for r in area if r["mesh"] == mesh and r["method"] == "gears" and r["knobs"].get("grid", 16) != 16]
        for r in other:  # grid changes time only (the grid is exact): crosses at the k=16 error
            ax.scatter([r["seconds"]], [max(r["error_mean"], 1e-6)], color=colors[mesh], marker="x", s=20)
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.xaxis.set_minor_formatter(plt.NullFormatter())  # a narrow time range crowds minor labels
    ax.set_title("rect-light visibility: GEARS (x: grid 8, 32) vs rays\n(different quantity from the transfer panels)",
                 fontsize=9)
    ax.set_xlabel("visibility time per frame [s]")
    ax.set_ylabel("mean |visible fraction − truth| (32×32 rays)")
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(fontsize=6)


def frontier_from_results(records: list[dict]) -> dict:
    """The planner's frontier: per method configuration, its worst mean error over the benchmark meshes
    and its measured time on each mesh (the planner scales the time of the mesh nearest in size).

    ``kwargs`` are the constructor keyword arguments the sweep passed (``knobs`` is what the method
    reported using, possibly with resolved sentinels).

    Returns:
        ``{"configs": [{"method", "order", "knobs", "kwargs", "error", "error_p95", "timings": [{"mesh", "vertices",
        "triangles", "seconds", "build_seconds"}]}], "area": [the same for area-light records, no order],
        "meshes": [...], "note": ...}``.
    """
    groups: dict[str, dict] = {}
    area: dict[str, dict] = {}
    for r in records:
        if "failed" in r:
            continue
        # area-light records (GEARS, rays) are not transfer methods: kept apart, no order
        into, ident = (area, [r["method"], r["knobs"]]) if is_area(r) else (groups, [r["method"], r["order"], r["knobs"]])
        key = json.dumps(ident, sort_keys=True, default=_jsonable)
        g = into.setdefault(key, {"method": r["method"], "order": r["order"], "knobs": r["knobs"],
                                  "kwargs": r.get("config", {}), "error": 0.0, "error_p95": 0.0, "timings": []})
        g["error"] = max(g["error"], r["error_mean"])
        g["error_p95"] = max(g["error_p95"], r["error_p95"])
        g["timings"].append({"mesh": r["mesh"], "vertices": r["vertices"], "triangles": r["triangles"],
                             "seconds": r["seconds"], "build_seconds": r.get("build_seconds", 0.0)})
    return {"configs": list(groups.values()), "area": list(area.values()),
            "meshes": sorted({t["mesh"] for g in groups.values() for t in g["timings"]}),
            "note": "error = worst error_mean over the benchmark meshes; timings measured by `warpshade bench`; "
                    "'area': rect-light visibility (GEARS, rays), error = absolute visible fraction"}
