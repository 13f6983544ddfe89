#!/usr/bin/env python3
"""Markdown tables from `dhoit bench` JSON: each method's steady-state GPU frame time, DKB's
ratios, and the passes where DKB and VKB differ.

    scripts/bench_table.py out/bench.json [more.json ...] > table.md
"""
import json
import sys


def table(path):
    with open(path) as f:
        report = json.load(f)
    gpu = report.get("gpu", {})
    if "error" in gpu:
        return f"`{path}`: no GPU ({gpu['error']})\n"
    out = [
        f"`{path}`: {gpu['adapter']}, {gpu['width']}x{gpu['height']}, budget {gpu['budget']}, "
        f"{report.get('repeat', '?')} steady frames (medians; passes from the fastest)\n",
        "| scene | A-buffer | FKB | optimal | VKB | DKB | DKB 16-8 | DKB/VKB | DKB/A-buffer "
        "| VKB count | DKB count + features | DKB importance (f16-math) | allocation "
        "| capture DKB / VKB | wall/(GPU + readback) |",
        "|---|" + "---:|" * 14,
    ]
    for s in gpu["scenes"]:
        if "error" in s:
            out.append(f"| {s['scene']} | error: {s['error']} |" + " |" * 13)
            continue
        m = s["methods"]

        def frame(k):
            return m[k]["frame_gpu_ms"]

        def p(k, name):
            # "-": the frame did not record that pass (DKB's importance where the budget
            # holds every fragment).
            ms = m[k]["passes_ms"].get(name)
            return "-" if ms is None else f"{ms:.2f}"

        # DKB's count pass, where it counts first (absent where the features pass counts), and
        # its features pass (absent where the frame expected to fit, and did).
        passes = m["dkb"]["passes_ms"]
        # The same importance pass at f16-math, where the bench ran it (the device has
        # SHADER_F16) and the frame recorded it.
        half = p("dkb_f16_math", "importance") if "dkb_f16_math" in m else "-"
        geometry = passes.get("count", 0.0) + passes.get("features", 0.0)
        out.append(
            f"| {s['scene']} | {frame('abuffer'):.2f} | {frame('fkb'):.2f} | {frame('optimal'):.2f} "
            f"| {frame('vkb'):.2f} | {frame('dkb'):.2f} | {frame('dkb_16-8'):.2f} "
            f"| {s['dkb_over_vkb']:.2f} | {s['dkb_over_abuffer']:.2f} | {p('vkb', 'count')} "
            f"| {geometry:.2f} | {p('dkb', 'importance')} ({half}) "
            f"| {p('dkb', 'allocation')} | {p('dkb', 'capture')} / {p('vkb', 'capture')} "
            f"| {m['dkb']['wall_over_gpu_plus_readback']:.2f} |"
        )
    return "\n".join(out) + "\n"


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    print("\n".join(table(p) for p in sys.argv[1:]))
