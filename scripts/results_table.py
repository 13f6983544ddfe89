#!/usr/bin/env python3
"""The documents' tables that `make eval` produces, from the tables it writes
(docs/eval-slots.md and docs/eval-materials-slots.md): the README's results table (mean MSE
against the A-buffer at equal F) and docs/results.md's accuracy targets, each between its
file's markers. `make eval` writes them (--write); `make test` checks them (--check: exit 1,
naming the first line that differs, where a document's table is not what the eval tables give;
and where the README is over 120 lines or has a paragraph over 8)."""
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
BUDGETS = ["10%", "25%", "50%", "1fpp", "2fpp"]
UNIFORM = ["fkb", "wboit", "mboit", "vkb", "dkb", "optimal-pooled", "optimal"]
MATERIALS = ["wboit", "mboit", "vkb", "dkb", "optimal-pooled", "optimal"]
BEGIN = "<!-- results: written by `make eval` from docs/eval-slots.md and docs/eval-materials-slots.md -->"
END = "<!-- /results -->"


def mse_table(path):
    """{budget: {method: text}} from the file's first table (mean MSE)."""
    rows = section(path, next(l[3:] for l in path.read_text().splitlines() if l.startswith("## Mean MSE")))
    header = [c.strip() for c in rows[0].strip("|").split("|")]
    table = {}
    for row in rows[2:]:
        cells = [c.strip() for c in row.strip("|").split("|")]
        table[cells[0]] = dict(zip(header, cells))
    return table


PRETTY = {"fkb": "FKB", "wboit": "WBOIT", "mboit": "MBOIT", "vkb": "VKB", "dkb": "DKB",
          "optimal": "optimal", "optimal-pooled": "pooled optimum", "mlab": "MLAB"}


def mse_rows(begin, budgets, uniform_cols, material_cols):
    """The MSE table at one opacity, then with the scenes' own materials, as `begin` names it."""
    uniform = mse_table(ROOT / "docs/eval-slots.md")
    materials = mse_table(ROOT / "docs/eval-materials-slots.md")
    head = (["budget"] + [PRETTY[m] for m in uniform_cols] + [""]
            + ["materials: " + PRETTY[material_cols[0]]] + [PRETTY[m] for m in material_cols[1:]])
    out = [begin, "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for b in budgets:
        label = b.replace("fpp", " fpp")
        cells = [label] + [uniform[b][m] for m in uniform_cols] + [""] + [materials[b][m] for m in material_cols]
        out.append("| " + " | ".join(cells) + " |")
    out.append(END)
    return "\n".join(out)


def rendered():
    return mse_rows(BEGIN, BUDGETS, UNIFORM, MATERIALS)


RESULTS_BEGIN = "<!-- mse: written by `make eval` from docs/eval-slots.md and docs/eval-materials-slots.md -->"


def results_mse():
    budgets = ["10%", "25%", "50%", "75%", "90%", "0.25fpp", "0.5fpp", "1fpp", "2fpp", "4fpp"]
    return mse_rows(RESULTS_BEGIN, budgets,
                    ["fkb", "vkb", "dkb", "optimal-pooled", "optimal", "mlab", "wboit"],
                    ["vkb", "dkb", "optimal-pooled", "optimal", "wboit"])


def section(path, title):
    """The lines of the Markdown table under `## title` in `path`."""
    lines = path.read_text().splitlines()
    start = lines.index(f"## {title}")
    first = next(i for i in range(start, len(lines)) if lines[i].startswith("|"))
    out = []
    for l in lines[first:]:
        if not l.startswith("|"):
            break
        out.append(l)
    return out


TARGETS_BEGIN = "<!-- targets: written by `make eval` from docs/eval-slots.md and docs/eval-materials-slots.md -->"


def targets():
    out = [TARGETS_BEGIN, "", "At one opacity (docs/eval-slots.md):", ""]
    out += section(ROOT / "docs/eval-slots.md", "Accuracy targets")
    out += ["", "With the scenes' own materials (docs/eval-materials-slots.md):", ""]
    out += section(ROOT / "docs/eval-materials-slots.md", "Accuracy targets")
    out += ["", END]
    return "\n".join(out)


BLOCKS = [
    ("README.md", BEGIN, rendered),
    ("docs/results.md", RESULTS_BEGIN, results_mse),
    ("docs/results.md", TARGETS_BEGIN, targets),
]


def readme_shape():
    """The README reads in five minutes: at most 120 lines, no paragraph over 8 (code blocks and
    tables aside). An error message, or None."""
    lines = (ROOT / "README.md").read_text().splitlines()
    if len(lines) > 120:
        return f"README.md is {len(lines)} lines (at most 120)"
    run, fenced = 0, False
    for n, l in enumerate(lines, 1):
        if l.startswith("```"):
            fenced = not fenced
            run = 0
            continue
        prose = not fenced and l.strip() and not l.startswith(("|", "<!--", "!["))
        # A list item starts a paragraph of its own.
        run = (1 if l.startswith("- ") else run + 1) if prose else 0
        if run > 8:
            return f"README.md line {n}: a paragraph over 8 lines"
    return None


def main():
    mode = sys.argv[1] if len(sys.argv) > 1 else "--check"
    failed = 0
    if mode == "--check" and (why := readme_shape()):
        print(f"results_table: {why}", file=sys.stderr)
        failed = 1
    for name, begin, make in BLOCKS:
        path = ROOT / name
        text = path.read_text()
        pattern = re.compile(re.escape(begin) + ".*?" + re.escape(END), re.S)
        found = pattern.search(text)
        if not found:
            print(f"results_table: {name} has no {begin!r} ... {END!r} block", file=sys.stderr)
            failed = 1
            continue
        table = make()
        if mode == "--write":
            path.write_text(pattern.sub(lambda _: table, text))
            print(f"results_table: {name}'s table written from docs/eval-*.md")
            continue
        if found.group(0) != table:
            for got, want in zip(found.group(0).splitlines(), table.splitlines()):
                if got != want:
                    print(f"results_table: {name} says\n  {got}\nwhere the eval tables give\n  {want}\n"
                          "(`make eval` writes it)", file=sys.stderr)
                    break
            failed = 1
        else:
            print(f"results_table: {name}'s table is the eval tables'")
    return failed


if __name__ == "__main__":
    sys.exit(main())
