#!/usr/bin/env python3
"""Fail when modules inside one crate import each other in a loop.

Each file module of each crate (`src/**/*.rs`) is a node; an edge `a -> b` says a file of `a`
names an item of `b` through a `crate::`, `super::` or child-module path (in a `use` or inline;
a `pub use` is a facade and is not counted). Re-exports
(`pub use x::Name`) are followed to the module that defines the name, so a parent that only
re-exports a child's item does not create a false edge. Inline modules belong to their file;
inline `#[cfg(test)]` modules are left out. Prints every cycle found (one per strongly connected component) and exits
1 if there is any.

Usage: scripts/module_cycles.py [CRATE_DIR…]   (default: every crates/*/ and the fuzz crate)
"""

from __future__ import annotations

import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

COMMENT = re.compile(r"//[^\n]*|/\*.*?\*/", re.S)
STRING = re.compile(r'r#*"(?:[^"]|"(?!#))*"#*|"(?:\\.|[^"\\])*"', re.S)
USE = re.compile(r"\b(pub(?:\([^)]*\))?\s+)?use\s+([^;]+);")
# Any path; only those starting at `crate`, `super`, `self` or a child module are resolved.
INLINE_PATH = re.compile(r"(?<![:\w])([A-Za-z_][A-Za-z0-9_]*(?:\s*::\s*[A-Za-z_][A-Za-z0-9_]*)+)")


TEST_MODULE = re.compile(r"#\[cfg\(test\)\]\s*(?:pub(?:\([^)]*\))?\s+)?mod\s+\w+\s*\{")


def strip(text: str) -> str:
    """Source without comments, string literals (their text is not code) and inline
    `#[cfg(test)]` modules (tests may reach anywhere; the loops that matter are the library's)."""
    text = COMMENT.sub(" ", STRING.sub('""', text))
    while (match := TEST_MODULE.search(text)) is not None:
        depth, end = 1, match.end()
        while depth and end < len(text):
            depth += (text[end] == "{") - (text[end] == "}")
            end += 1
        text = text[: match.start()] + text[end:]
    return text


def module_of(src: Path, file: Path) -> tuple[str, ...]:
    rel = file.relative_to(src).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] in ("lib", "main", "mod"):
        parts.pop()
    return tuple(parts)


def split_top(s: str) -> list[str]:
    """Split at the commas outside braces."""
    out, depth, cur = [], 0, ""
    for ch in s:
        if ch == "," and depth == 0:
            out.append(cur)
            cur = ""
            continue
        depth += (ch == "{") - (ch == "}")
        cur += ch
    return out + [cur] if cur else out


def expand_use(tree: str) -> list[list[str]]:
    """`a::{b, c::{d, e as f}, self}` -> [[a,b], [a,c,d], [a,c,e], [a]] (aliases dropped)."""
    tree = re.sub(r"\s+as\s+[A-Za-z_][A-Za-z0-9_]*", "", tree)
    tree = re.sub(r"\s+", "", tree)

    def walk(prefix: list[str], s: str) -> list[list[str]]:
        if not s:
            return []
        brace = s.find("{")
        if brace >= 0:
            head = [p for p in s[:brace].split("::") if p]
            inner = s[brace + 1 : s.rfind("}")]
            return [path for item in split_top(inner) for path in walk(prefix + head, item)]
        parts = [p for p in s.split("::") if p]
        if parts and parts[-1] == "self":
            parts.pop()
        return [prefix + parts]

    return walk([], tree)


class Crate:
    def __init__(self, crate_dir: Path) -> None:
        self.name = crate_dir.name
        src = crate_dir / "src"
        self.files: dict[tuple[str, ...], list[str]] = {}
        for file in sorted(src.rglob("*.rs")):
            module = module_of(src, file)
            self.files.setdefault(module, []).append(strip(file.read_text(encoding="utf-8")))
        self.modules = set(self.files)
        # (module, exported name) -> absolute path it re-exports.
        self.reexports: dict[tuple[tuple[str, ...], str], list[str]] = {}
        for module, texts in self.files.items():
            for text in texts:
                for match in USE.finditer(text):
                    if not match.group(1):
                        continue
                    for path in expand_use(match.group(2)):
                        absolute = self.absolute(module, path)
                        if absolute and absolute[-1] != "*":
                            self.reexports[(module, absolute[-1])] = absolute

    def absolute(self, module: tuple[str, ...], path: list[str]) -> list[str] | None:
        """A `crate::`/`super::`/`self::` path, or one starting at a child module, as a list of
        names from the crate root."""
        if not path:
            return None
        if module + (path[0],) in self.modules:
            return list(module) + path
        if path[0] == "crate":
            return path[1:]
        if path[0] in ("super", "self"):
            base = list(module)
            while path and path[0] in ("super", "self"):
                if path[0] == "super":
                    if not base:
                        return None
                    base.pop()
                path = path[1:]
            return base + path
        return None

    def defining_module(self, absolute: list[str], seen: int = 0) -> tuple[str, ...] | None:
        """The file module that defines the item `absolute` names (re-exports followed)."""
        for cut in range(len(absolute), -1, -1):
            prefix = tuple(absolute[:cut])
            if prefix in self.modules:
                rest = absolute[cut:]
                if rest and seen < 16:
                    target = self.reexports.get((prefix, rest[0]))
                    if target is not None and target != absolute:
                        return self.defining_module(target + rest[1:], seen + 1) or prefix
                return prefix
        return None

    def edges(self) -> dict[tuple[str, ...], set[tuple[str, ...]]]:
        graph: dict[tuple[str, ...], set[tuple[str, ...]]] = {m: set() for m in self.modules}
        for module, texts in self.files.items():
            for text in texts:
                paths: list[list[str]] = []
                for match in USE.finditer(text):
                    # A `pub use` is a facade (a parent re-exporting its child's items), not a
                    # dependency; what the items themselves use is counted where they live.
                    if not match.group(1):
                        paths += expand_use(match.group(2))
                for match in INLINE_PATH.finditer(USE.sub(" ", text)):
                    paths.append(re.sub(r"\s+", "", match.group(1)).split("::"))
                for path in paths:
                    absolute = self.absolute(module, path)
                    if absolute is None:
                        continue
                    if absolute and absolute[-1] == "*":
                        absolute = absolute[:-1]
                    target = self.defining_module(absolute)
                    if target is not None and target != module:
                        graph[module].add(target)
        return graph


def strongly_connected(graph: dict) -> list[list]:
    index: dict = {}
    low: dict = {}
    stack: list = []
    on_stack: set = set()
    components: list[list] = []
    counter = [0]

    def visit(v) -> None:
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            components.append(component)

    sys.setrecursionlimit(10000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return [c for c in components if len(c) > 1]


def name(module: tuple[str, ...]) -> str:
    return "::".join(module) or "(crate root)"


def main(argv: list[str]) -> int:
    dirs = [Path(a) for a in argv] or sorted(
        [p for p in (ROOT / "crates").iterdir() if (p / "src").is_dir()]
        + [p for p in [ROOT / "fuzz"] if (p / "src").is_dir()]
    )
    loops = 0
    for crate_dir in dirs:
        crate = Crate(crate_dir)
        graph = crate.edges()
        for component in strongly_connected(graph):
            loops += 1
            members = set(component)
            lines = [
                f"  {name(a)} -> {name(b)}"
                for a in sorted(members)
                for b in sorted(graph[a] & members)
            ]
            print(f"{crate.name}: import loop among {', '.join(sorted(map(name, members)))}")
            print("\n".join(lines))
    if loops:
        print(f"{loops} import loop(s); modules in a crate must form a DAG (docs/ARCHITECTURE.md)")
        return 1
    print("no import loops")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
