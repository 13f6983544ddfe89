#!/usr/bin/env python3
"""The documents' tables that the commands produce, from the files those commands write.

- The README's results table (mean MSE against the A-buffer at equal F) and docs/results.md's
  MSE table and accuracy targets, from `make eval`'s docs/eval-slots.md and
  docs/eval-materials-slots.md.
- docs/results.md's summary of `make versus` (docs/versus.md): each method's frames and MSE at
  each memory.
- Any table a document copies: between `<!-- table: FILE "HEADING" -->` (or `... "HEADING" N`
  for the Nth table under it) and `<!-- /table -->`, the table under that heading in FILE (a
  path from the repository root), in README.md and docs/*.md alike.
- docs/training.md's figures of the default training (its samples, epochs and the training
  machine's float fingerprint), held to the data/config.json that `make train` writes.

`make eval` (and `make versus`, `make trade`, `make frame`) write them (--write); `make test`
checks them (--check: exit 1, naming the first line that differs, where a document's table is
not what its source gives; and where the README is over 120 lines or has a paragraph over 8)."""
import json
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
    rows = section(path, "Mean MSE")
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


def tables_under(lines, heading):
    """The Markdown tables (each its lines) under the first heading of `lines` whose text starts
    with `heading`, up to the next heading after them; None where no heading starts so."""
    start = next((i for i, l in enumerate(lines)
                  if l.startswith("#") and l.lstrip("#").strip().startswith(heading)), None)
    if start is None:
        return None
    tables, current = [], None
    for l in lines[start + 1:]:
        if l.startswith("#") and tables:
            break
        if l.startswith("|"):
            if current is None:
                current = []
                tables.append(current)
            current.append(l)
        else:
            current = None
    return tables


def section(path, heading):
    """The lines of the first Markdown table under the heading of `path` that starts with
    `heading`."""
    return tables_under(path.read_text().splitlines(), heading)[0]


TARGETS_BEGIN = "<!-- targets: written by `make eval` from docs/eval-slots.md and docs/eval-materials-slots.md -->"


def targets():
    out = [TARGETS_BEGIN, "", "At one opacity (docs/eval-slots.md):", ""]
    out += section(ROOT / "docs/eval-slots.md", "Accuracy targets")
    out += ["", "With the scenes' own materials (docs/eval-materials-slots.md):", ""]
    out += section(ROOT / "docs/eval-materials-slots.md", "Accuracy targets")
    out += ["", END]
    return "\n".join(out)


VERSUS_BEGIN = "<!-- versus: written by `make versus` from docs/versus.md -->"


def versus():
    """Each method's frames of the run and geometric-mean MSE at each memory, from the table
    at the head of each of docs/versus.md's `## M = ...` sections."""
    lines = (ROOT / "docs/versus.md").read_text().splitlines()
    memories = [l[len("## M = "):].split("x")[0] + "x" for l in lines if l.startswith("## M = ")]
    runs, order, total = {}, [], None
    for m in memories:
        rows = tables_under(lines, f"M = {m}")[0]
        header = [c.strip() for c in rows[0].strip("|").split("|")]
        for row in rows[2:]:
            cell = dict(zip(header, (c.strip() for c in row.strip("|").split("|"))))
            name = cell["method"]
            if name not in runs:
                runs[name] = {}
                order.append(name)
            # "1 of 15": the frames it ran of the run's, the same at every memory.
            frames, total = cell["frames"].split(" of ")
            runs[name][m] = f"{frames}: {cell['MSE']}"
    head = ["method"] + [f"M = {m}: frames of {total}: MSE" for m in memories]
    out = [VERSUS_BEGIN, "| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    for name in order:
        out.append("| " + " | ".join([name] + [runs[name].get(m, "-") for m in memories]) + " |")
    out.append(END)
    return "\n".join(out)


BLOCKS = [
    ("README.md", BEGIN, rendered),
    ("docs/results.md", RESULTS_BEGIN, results_mse),
    ("docs/results.md", TARGETS_BEGIN, targets),
    ("docs/results.md", VERSUS_BEGIN, versus),
]

COPY = re.compile(r'<!-- table: (\S+) "([^"]*)"(?: (\d+))? -->\n(.*?)<!-- /table -->', re.S)


def copied(source, heading, n):
    """The `n`th table (from 1) under the first heading of `source` whose text starts with
    `heading`, as its lines; an error message where there is none."""
    path = ROOT / source
    if not path.is_file():
        return f"{source} does not exist"
    tables = tables_under(path.read_text().splitlines(), heading)
    if tables is None:
        return f'{source} has no heading "{heading}"'
    if len(tables) < n:
        return f'{source} has {len(tables)} tables under "{heading}", not {n}'
    return tables[n - 1]


def copies(mode):
    """Every `<!-- table: ... -->` block of README.md and docs/*.md held to (--check) or
    rewritten from (--write) its source. The number of failures."""
    failed = 0
    for path in [ROOT / "README.md"] + sorted((ROOT / "docs").glob("*.md")):
        text = path.read_text()
        name = path.relative_to(ROOT)
        out, changed = [], False
        last = 0
        for m in COPY.finditer(text):
            source, heading, n = m.group(1), m.group(2), int(m.group(3) or 1)
            table = copied(source, heading, n)
            if isinstance(table, str):
                print(f"results_table: {name}: {table}", file=sys.stderr)
                failed += 1
                continue
            body = "\n".join(table) + "\n"
            if m.group(4) != body:
                if mode == "--write":
                    out.append(text[last:m.start(4)] + body)
                    last = m.end(4)
                    changed = True
                    continue
                got = m.group(4).splitlines() + [""]
                first = next(i for i, (a, b) in enumerate(zip(got, table + [""])) if a != b)
                print(f'results_table: {name} copies {source} "{heading}" but says\n  {got[first]}\n'
                      f"where {source} gives\n  {(table + [''])[first]}\n(--write copies it)", file=sys.stderr)
                failed += 1
        if changed:
            path.write_text("".join(out) + text[last:])
            print(f"results_table: {name}'s copied tables written")
    return failed


def claims():
    """The README's sentences on its results table, held to that table (the sentence must be
    there, word for word, and true of every row). Error messages."""
    text = (ROOT / "README.md").read_text()
    found = re.search(re.escape(BEGIN) + "\n(.*?)" + re.escape(END), text, re.S)
    if not found:
        return ["README.md has no results table"]
    rows = found.group(1).strip().splitlines()
    header = [c.strip() for c in rows[0].strip("|").split("|")]
    gap = header.index("")
    sets = [("one opacity", 0, gap), ("materials", gap + 1, len(header))]
    errors = []

    def value(cells, set_, name):
        _, lo, hi = set_
        i = next(i for i in range(lo, hi) if header[i].replace("materials: ", "") == name)
        return float(cells[i]) if cells[i] not in ("n/a", "-") else None

    said = [
        "DKB's error is below VKB's (the hand-made allocation it learns to beat) and WBOIT's (what\n"
        "engines ship) at every budget here.",
        "MBOIT, at 28 bytes a pixel, is better only at the tightest;",
    ]
    for sentence in said:
        if sentence not in text:
            errors.append(f"README.md no longer says {sentence!r}: update scripts/results_table.py's claims")
    rows = [[c.strip() for c in row.strip("|").split("|")] for row in rows[2:]]
    tightest = rows[0][0]
    for cells in rows:
        for set_ in sets:
            dkb = value(cells, set_, "DKB")
            for other in ["VKB", "WBOIT"]:
                v = value(cells, set_, other)
                if v is not None and not dkb < v:
                    errors.append(f"README.md says DKB's error is below {other}'s at every budget; "
                                  f"at {cells[0]} ({set_[0]}) DKB {dkb:.3e}, {other} {v:.3e}")
            mboit = value(cells, set_, "MBOIT")
            if mboit is not None and mboit < dkb and cells[0] != tightest:
                errors.append(f"README.md says MBOIT is better only at the tightest budget; "
                              f"at {cells[0]} ({set_[0]}) MBOIT {mboit:.3e}, DKB {dkb:.3e}")
    return errors


def training_claims():
    """docs/training.md's figures of the default training held to data/config.json (what `make
    train` writes beside the weights). Error messages."""
    text = (ROOT / "docs/training.md").read_text()
    config = json.loads((ROOT / "data/config.json").read_text())
    samples, epochs = config["dataset"]["samples"], config["train"]["epochs"]
    figures = [
        (r"\((\d+\.\d) million\s+samples\)", f"{samples / 1e6:.1f}", f"{samples:,} samples"),
        (r"then trains (\d+) epochs", str(epochs), f"{epochs} epochs"),
        (r"records the training machine's \(`([0-9a-z-]+)`", config["float_fingerprint"],
         "the training machine's float fingerprint"),
    ]
    errors = []
    for pattern, want, recorded in figures:
        found = re.search(pattern, text)
        if not found:
            errors.append(f"docs/training.md has no {pattern!r}: update scripts/results_table.py")
        elif found.group(1) != want:
            errors.append(f"docs/training.md says {found.group(0)!r}; data/config.json records "
                          f"{recorded} ({want})")
    return errors


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
    failed = min(1, failed + copies(mode))
    if mode == "--check":
        for why in claims() + training_claims():
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
            print(f"results_table: {name}: {begin[5:begin.index(':')]} written")
            continue
        if found.group(0) != table:
            for got, want in zip(found.group(0).splitlines(), table.splitlines()):
                if got != want:
                    command = re.search(r"written by (`make \w+`)", begin).group(1)
                    print(f"results_table: {name} says\n  {got}\nwhere its source gives\n  {want}\n"
                          f"({command} writes it)", file=sys.stderr)
                    break
            failed = 1
        else:
            print(f"results_table: {name}: {begin[5:begin.index(':')]} is its source's")
    return failed


if __name__ == "__main__":
    sys.exit(main())
