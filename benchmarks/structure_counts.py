"""Structure counts of the source tree (issue 36): what the closing note compares before and after.

Run from the repository root::

    python benchmarks/structure_counts.py [--json]

Counts, over ``models/``, ``problems/`` and ``planner/`` (tests and benchmarks left out):

- source lines (every line of every ``.py`` file);
- files over 600 lines, functions over 80 lines (a function's span from its ``def`` to its last line);
- import circles: strongly connected components of the module graph built from every import
  statement that runs at import time or inside a function (imports under ``if TYPE_CHECKING:`` are
  counted apart as type-only); a package's ``__init__`` is a module of its own;
- ``_private`` cross-imports: ``from X import _name`` (or ``X._name`` attribute use after
  ``import X``) where ``X`` is another module of the product;
- exported names: the sum of the lengths of every ``__all__`` list.
"""

from __future__ import annotations

import argparse
import ast
import json
import sys
from pathlib import Path

PACKAGES = ("models", "problems", "planner")
LONG_FILE_LINES = 600
LONG_FUNCTION_LINES = 80


def module_name(root: Path, path: Path) -> str:
    parts = list(path.relative_to(root).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def resolve(module: str, is_package: bool, level: int, target: str | None) -> str:
    if level == 0:
        return target or ""
    base = module.split(".")
    if not is_package:
        base = base[:-1]
    if level > 1:
        base = base[: len(base) - (level - 1)]
    return ".".join(base + ([target] if target else []))


def _is_type_checking(node: ast.If) -> bool:
    test = node.test
    return (isinstance(test, ast.Name) and test.id == "TYPE_CHECKING") or (
        isinstance(test, ast.Attribute) and test.attr == "TYPE_CHECKING"
    )


def collect(root: Path) -> dict:
    files = sorted(p for pkg in PACKAGES for p in (root / pkg).rglob("*.py"))
    modules = {module_name(root, p): p for p in files}
    lines = 0
    long_files = []
    long_functions = []
    exported = 0
    edges: dict[str, set[str]] = {m: set() for m in modules}
    type_edges: dict[str, set[str]] = {m: set() for m in modules}
    private = []

    def known(name: str) -> str | None:
        while name:
            if name in modules:
                return name
            name = name.rpartition(".")[0]
        return None

    for mod, path in modules.items():
        text = path.read_text(encoding="utf-8")
        n = text.count("\n") + (0 if text.endswith("\n") else 1)
        lines += n
        if n > LONG_FILE_LINES:
            long_files.append((str(path.relative_to(root)), n))
        tree = ast.parse(text)
        is_package = path.name == "__init__.py"
        type_nodes: set[int] = set()
        for node in ast.walk(tree):
            if isinstance(node, ast.If) and _is_type_checking(node):
                for sub in node.body:
                    for inner in ast.walk(sub):
                        type_nodes.add(id(inner))
        for node in ast.walk(tree):
            if isinstance(node, ast.FunctionDef | ast.AsyncFunctionDef):
                span = node.end_lineno - node.lineno + 1
                if span > LONG_FUNCTION_LINES:
                    long_functions.append((f"{path.relative_to(root)}:{node.name}", span))
            is_all = isinstance(node, ast.Assign) and any(
                isinstance(t, ast.Name) and t.id == "__all__" for t in node.targets
            )
            if is_all:
                if isinstance(node.value, ast.List | ast.Tuple):
                    exported += len(node.value.elts)
            if isinstance(node, ast.ImportFrom):
                target = resolve(mod, is_package, node.level, node.module)
                for alias in node.names:
                    full = known(f"{target}.{alias.name}") if target else None
                    dest = full if full and full != known(target) else known(target)
                    if dest is None:
                        continue
                    graph = type_edges if id(node) in type_nodes else edges
                    if dest != mod:
                        graph[mod].add(dest)
                    if alias.name.startswith("_") and not alias.name.startswith("__") and dest != mod:
                        private.append(f"{path.relative_to(root)}: {target}.{alias.name}")
            elif isinstance(node, ast.Import):
                for alias in node.names:
                    dest = known(alias.name)
                    if dest and dest != mod:
                        (type_edges if id(node) in type_nodes else edges)[mod].add(dest)
    circles = strongly_connected([m for m in modules], edges)
    all_edges = {m: edges[m] | type_edges[m] for m in modules}
    circles_with_types = strongly_connected([m for m in modules], all_edges)
    return {
        "source_lines": lines,
        "files": len(files),
        "files_over_600": sorted(long_files, key=lambda t: -t[1]),
        "functions_over_80": sorted(long_functions, key=lambda t: -t[1]),
        "import_circles": circles,
        "import_circles_counting_type_only": circles_with_types,
        "private_cross_imports": private,
        "exported_names": exported,
    }


def strongly_connected(nodes: list[str], edges: dict[str, set[str]]) -> list[list[str]]:
    """Tarjan's algorithm (iterative); components of more than one module."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out: list[list[str]] = []
    counter = 0
    for start in nodes:
        if start in index:
            continue
        work = [(start, iter(sorted(edges[start])))]
        index[start] = low[start] = counter
        counter += 1
        stack.append(start)
        on.add(start)
        while work:
            v, it = work[-1]
            advanced = False
            for w in it:
                if w not in index:
                    index[w] = low[w] = counter
                    counter += 1
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(edges[w]))))
                    advanced = True
                    break
                if w in on:
                    low[v] = min(low[v], index[w])
            if advanced:
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
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
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--json", action="store_true", help="print every list in full, as JSON")
    parser.add_argument("--root", type=Path, default=Path(__file__).resolve().parent.parent)
    args = parser.parse_args(argv)
    counts = collect(args.root)
    if args.json:
        json.dump(counts, sys.stdout, indent=1)
        print()
        return 0
    print(f"source lines                  {counts['source_lines']} in {counts['files']} files")
    print(f"files over {LONG_FILE_LINES} lines         {len(counts['files_over_600'])}")
    print(f"functions over {LONG_FUNCTION_LINES} lines      {len(counts['functions_over_80'])}")
    sizes = [len(c) for c in counts["import_circles"]]
    print(f"import circles (run time)     {len(sizes)} (modules in them: {sizes})")
    sizes_t = [len(c) for c in counts["import_circles_counting_type_only"]]
    print(f"  counting type-only imports  {len(sizes_t)} ({sizes_t})")
    print(f"_private cross-imports        {len(counts['private_cross_imports'])}")
    print(f"exported names (__all__)      {counts['exported_names']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
