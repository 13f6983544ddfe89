#!/usr/bin/env python3
"""The web build's measured figures as Markdown, from the JSON that scripts/web.sh test's runs
leave in DIR (web_test.mjs's summary-page.json and summary-all.json, web_page.mjs's page.json):
each wasm frame on Dawn against the native one, and the times. `web.sh record` keeps it as
docs/web-measured.md, which docs/web.md copies.

    web_summary.py DIR > measured.md
"""
import json
import sys
from pathlib import Path


def count(n):
    return f"{n:,}"


def main(folder):
    d = Path(folder)
    runs = [json.loads((d / f"summary-{r}.json").read_text()) for r in ("page", "all")]
    page = json.loads((d / "page.json").read_text())
    first = runs[0]
    w, h = first["size"]
    out = [
        "# The web build, measured",
        "",
        f"`scripts/web.sh record`: the wasm build on Dawn ({first['adapter']}) against the",
        f"native build on WebGPU's core device, the built-in {first['scene']} scene at {w}x{h}.",
        "",
        "## Frames against the native build",
        "",
        "| budget | method | bytes (native) | every fragment | linear values differing | "
        "sRGB8 channels differing (by at most) | error against the A-buffer, over native |",
        "|---|---|---:|---|---|---|---:|",
    ]
    for run in runs:
        for v in run["views"]:
            ratio = "-" if v["order_independent"] else f"{v['rmse_ratio']:.2f}x"
            out.append(
                f"| {run['budget']} | {v['method']} | {count(v['bytes'])} ({count(v['native_bytes'])}) "
                f"| {'yes' if v['exact'] else 'no'} "
                f"| {count(v['linear_differ'])} of {count(v['linear_values'])} "
                f"| {count(v['srgb_differ'])} of {count(v['srgb_channels'])} ({v['srgb_most']}) | {ratio} |")
    h = first["host"]
    out += [
        "",
        "## The hosts' maths",
        "",
        "| words the wasm host computed otherwise than the native one | differing |",
        "|---|---|",
        f"| camera | {h['camera_differ']} of {count(h['camera_words'])} |",
        f"| vertices | {count(h['vertex_differ'])} of {count(h['vertex_words'])} |",
    ]
    pw, ph = page["size"]
    out += [
        "",
        "## Times",
        "",
        "| what | ms |",
        "|---|---:|",
    ]
    for run in runs:
        names = ", ".join(v["method"] for v in run["views"])
        frames = sum(v["frames"] for v in run["views"])
        out.append(f"| Dawn: {names} at {run['budget']} ({frames} frames) | {run['ms']:.0f} |")
    out += [
        f"| Chromium (SwiftShader), the page at {pw}x{ph}: its first render | {page['first_ms']} |",
        f"| the same, the scene {page['scene']} | {page['scene_ms']} |",
        "",
    ]
    return "\n".join(out)


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    sys.stdout.write(main(sys.argv[1]))
