#!/usr/bin/env python3
"""Import circles between the modules of dhoit's crates, which `make test` requires to be none.

Each `.rs` file is a module (`mod.rs` the folder's). A module imports another where its code
(unit tests left out) names it: `use crate::a::...`, `crate::a::b::...` in a path, `super::x`
inside a folder. A folder's `mod.rs` declares and re-exports its children; what it names of
them is not counted, what they name of it is. A circle is a set of modules each reaching every
other through imports (a strongly connected component of more than one).

    scripts/module_cycles.py [--graph]   # each circle, exit 1 where there is one; --graph
                                         # prints every module's imports too

`make test` runs it: a change that closes a circle fails the tests. The layering it keeps in
the runtime, lowest first: shared, error, fragment, alloc, importance, mlp, budget, method,
plan, scene, raster, composite, frame, wgsl; in `gpu/`, shader and buffers below passes and
timer, the methods' passes above them, the clients (scene, app, stream, hooks) on top.
"""
import re
import sys
from pathlib import Path

CRATES = {"dhoit_runtime": "runtime/src", "dhoit_train": "train/src", "dhoit": "src"}
ROOTS = ("lib.rs", "main.rs")


def modules(src: Path):
    """Module path ('gpu::scene') -> file, for every file of a crate."""
    out = {}
    for f in sorted(src.rglob("*.rs")):
        rel = f.relative_to(src)
        if rel.as_posix() in ROOTS:
            continue
        parts = list(rel.with_suffix("").parts)
        if parts[-1] == "mod":
            parts.pop()
        out["::".join(parts)] = f
    return out


def code(text: str) -> str:
    """The file's code: comments out, and a trailing `#[cfg(test)] mod tests` left out."""
    text = re.sub(r"//[^\n]*", "", text)
    m = re.search(r"#\[cfg\(test\)\]\s*mod tests\s*\{", text)
    return text[: m.start()] if m else text


def use_paths(tree: str, prefix: list):
    """Every path a `use` tree names (`a::{b, c::d}`), as lists of segments."""
    tree = tree.strip()
    depth, start, items = 0, 0, []
    if "{" in tree and tree.endswith("}"):
        head, body = tree.split("{", 1)
        head = [s for s in head.split("::") if s]
        body = body[:-1]
        for i, ch in enumerate(body + ","):
            if ch == "{":
                depth += 1
            elif ch == "}":
                depth -= 1
            elif ch == "," and depth == 0:
                items.append(body[start:i])
                start = i + 1
        for item in items:
            if item.strip():
                yield from use_paths(item, prefix + head)
        return
    path = [s.strip() for s in tree.split(" as ")[0].split("::") if s.strip()]
    yield prefix + path


def references(text: str):
    """Every path the code names that starts at `crate` or `super`."""
    for m in re.finditer(r"\buse\s+([^;]+);", text):
        for p in use_paths(m.group(1), []):
            if p and p[0] in ("crate", "super"):
                yield p
    for m in re.finditer(r"\b((?:crate|super)(?:::\w+)+)", text):
        yield m.group(1).split("::")


def graph(src: Path):
    mods = modules(src)
    edges = {m: set() for m in mods}
    for m, f in mods.items():
        here = m.split("::")
        # The folder a `super::` starts from: a file's parent module.
        parent = here[:-1]
        for p in references(code(f.read_text())):
            base, rest = (parent, p[1:]) if p[0] == "super" else ([], p[1:])
            # The longest module the path names.
            target = None
            for n in range(len(rest), 0, -1):
                cand = "::".join(base + rest[:n])
                if cand in mods:
                    target = cand
                    break
            if target is None and base:
                target = "::".join(base)
            if target is None or target == m or target not in mods:
                continue
            # A folder's mod.rs naming its own children: declaring, not importing.
            if f.name == "mod.rs" and target.startswith(m + "::"):
                continue
            edges[m].add(target)
    return edges


def circles(edges):
    """Tarjan's strongly connected components of more than one module."""
    index, low, stack, on, out = {}, {}, [], set(), []
    counter = [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in sorted(edges[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    sys.setrecursionlimit(10000)
    for v in sorted(edges):
        if v not in index:
            visit(v)
    return out


def main():
    root = Path(__file__).resolve().parent.parent
    found = 0
    for crate, src in CRATES.items():
        edges = graph(root / src)
        if "--graph" in sys.argv:
            for m in sorted(edges):
                print(f"{crate}::{m} -> {', '.join(sorted(edges[m])) or '-'}")
        for c in circles(edges):
            found += 1
            inner = [f"{a} -> {b}" for a in c for b in sorted(edges[a]) if b in c]
            print(f"{crate}: an import circle among {', '.join(c)} ({'; '.join(inner)})")
    if found:
        print(f"modules: {found} import circle(s)")
        sys.exit(1)
    print("modules: no import circle in " + ", ".join(CRATES))


if __name__ == "__main__":
    main()
