#!/usr/bin/env python3
"""Fail when modules inside one crate import each other in a loop.

Each file module of a crate is a node (found by following `mod` declarations from `src/lib.rs`,
`src/main.rs` and `src/bin/*.rs`, `#[path]` honoured; inline modules belong to their file).
An edge `a -> b` says code in `a` names an item that `b` defines, through a `crate::`,
`$crate::`, `super::` or `self::` path, a path starting at a child module or at a name the
module imported, in a `use` (groups `{b, c::{d}}`, globs, `as` renames) or inline in code
(`crate::x::f()`, types, patterns, macro paths). Names are followed through every `use` to the
module that defines them, so a parent that only re-exports a child's item is not a false edge.
A `pub use` of the module's own descendants that its own code never names is a facade, not an
edge; every other `use` is one (a private import never named may bring a trait's methods).
Test code (`#[cfg(test)]` modules, inline or file, and `#[cfg(test)]` items) is left out:
tests may reach anywhere, the loops that matter are the library's. Not seen: macros called by
bare name (`foo!`, textually scoped), names a macro builds, and a parent calling methods of a
trait it re-exports from a child without naming it.

Prints every loop (one per strongly connected component) with its edges and exits 1 if there is
any. `scripts/module_cycles_test.py` tests the checker itself on small made-up crates.

Usage: scripts/module_cycles.py [CRATE_DIR…]   (default: every crates/*/, tests/ and fuzz/)
"""

from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent

Scope = tuple[str, ...]
ITEM_KEYWORDS = {"fn", "struct", "enum", "trait", "type", "const", "static", "union", "mod"}


def lex(text: str) -> list[tuple[str, str]]:
    """Tokens `(kind, text)`, kind `id` (identifiers and keywords, `r#` dropped), `str` (a
    string literal's contents) or `p` (punctuation; `::` is one token). Comments (nested block
    comments too), char literals and lifetimes are dropped."""
    out: list[tuple[str, str]] = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if c.isspace():
            i += 1
        elif text.startswith("//", i):
            end = text.find("\n", i)
            i = n if end < 0 else end
        elif text.startswith("/*", i):
            depth, i = 1, i + 2
            while i < n and depth:
                if text.startswith("/*", i):
                    depth, i = depth + 1, i + 2
                elif text.startswith("*/", i):
                    depth, i = depth - 1, i + 2
                else:
                    i += 1
        elif c in "rb" and (raw := _raw_string(text, i)) is not None:
            out.append(("str", text[raw[0] : raw[1]]))
            i = raw[2]
        elif c == '"' or (c == "b" and text.startswith('b"', i)):
            i += 1 if c == '"' else 2
            start = i
            while i < n and text[i] != '"':
                i += 2 if text[i] == "\\" else 1
            out.append(("str", text[start:i]))
            i += 1
        elif c == "'" or (c == "b" and text.startswith("b'", i)):
            i += 1 if c == "'" else 2
            if text.startswith("\\", i):  # an escaped char literal
                i = text.find("'", i + 2) + 1 or n
            elif i + 1 < n and text[i + 1] == "'":  # a one-character literal ('"', 'a')
                i += 2
            else:  # a lifetime or label: skip its name
                while i < n and (text[i].isalnum() or text[i] == "_"):
                    i += 1
        elif c.isalpha() or c == "_":
            start = i
            while i < n and (text[i].isalnum() or text[i] == "_"):
                i += 1
            if text[start:i] == "r" and text.startswith("#", i) and i + 1 < n and (text[i + 1].isalpha() or text[i + 1] == "_"):
                start = i = i + 1  # a raw identifier `r#name`
                while i < n and (text[i].isalnum() or text[i] == "_"):
                    i += 1
            out.append(("id", text[start:i]))
        elif c.isdigit():
            while i < n and (text[i].isalnum() or text[i] in "_."):
                if text[i] == "." and not (i + 1 < n and text[i + 1].isdigit()):
                    break
                i += 1
        elif text.startswith("::", i):
            out.append(("p", "::"))
            i += 2
        else:
            out.append(("p", c))
            i += 1
    return out


def _raw_string(text: str, i: int) -> tuple[int, int, int] | None:
    """`r"…"`, `r#"…"#`, `br"…"` at `i`: (content start, content end, next index)."""
    j = i + (2 if text.startswith("br", i) else 1 if text[i] == "r" else 0)
    if j == i or (i > 0 and (text[i - 1].isalnum() or text[i - 1] == "_")):
        return None
    hashes = 0
    while j < len(text) and text[j] == "#":
        hashes, j = hashes + 1, j + 1
    if j >= len(text) or text[j] != '"':
        return None
    close = text.find('"' + "#" * hashes, j + 1)
    close = len(text) if close < 0 else close
    return j + 1, close, close + 1 + hashes


@dataclass
class Use:
    scope: Scope
    path: list[str]  # as written, `*` last for a glob
    alias: str | None  # the name bound (None for globs and `as _`)
    public: bool


@dataclass
class Crate:
    name: str
    scopes: dict[Scope, Scope] = field(default_factory=dict)  # scope -> its file module
    defs: dict[Scope, set[str]] = field(default_factory=dict)
    uses: list[Use] = field(default_factory=list)
    paths: list[tuple[Scope, list[str]]] = field(default_factory=list)  # inline paths
    words: dict[Scope, set[str]] = field(default_factory=dict)  # identifiers in code, not in uses

    def load(self, root_file: Path) -> "Crate":
        self._file((), root_file, root_file.parent)
        self.bindings: dict[tuple[Scope, str], Use] = {}
        self.globs: dict[Scope, list[Use]] = {}
        for use in self.uses:
            if use.path and use.path[-1] == "*":
                self.globs.setdefault(use.scope, []).append(use)
            elif use.alias is not None:
                self.bindings[(use.scope, use.alias)] = use
        return self

    def _file(self, module: Scope, file: Path, child_dir: Path) -> None:
        tokens = lex(file.read_text(encoding="utf-8"))
        self.scopes[module] = module
        self.defs.setdefault(module, set())
        _Reader(self, tokens, module, file).block(0, module, child_dir)


class _Reader:
    """Walks one file's tokens: scopes, `mod` declarations, uses, definitions, inline paths."""

    def __init__(self, crate: Crate, tokens, file_module: Scope, file: Path):
        self.crate, self.t, self.file_module, self.file = crate, tokens, file_module, file

    def tok(self, i: int) -> tuple[str, str]:
        return self.t[i] if i < len(self.t) else ("p", "")

    def block(self, i: int, scope: Scope, child_dir: Path) -> int:
        """Reads items of `scope` from token `i` to the `}` closing it (or the end); returns the
        index after that brace."""
        depth = 0  # braces opened inside this scope (function bodies, impls…)
        test_attr = False
        path_attr: str | None = None
        while i < len(self.t):
            kind, text = self.t[i]
            if text == "#" and kind == "p" and self.tok(i + 1)[1] in ("[", "!"):
                inner_attr = self.tok(i + 1)[1] == "!"
                start = i + (3 if inner_attr else 2)
                end = self.skip_group(start - 1)
                attr = [tx for _, tx in self.t[start : end - 1]]
                if attr == ["cfg", "(", "test", ")"]:
                    if inner_attr:  # `#![cfg(test)]`: the whole scope is test code
                        return self.skip_to_scope_end(end, depth)
                    test_attr = True
                if attr[:2] == ["path", "="] and self.t[end - 2][0] == "str":
                    path_attr = self.t[end - 2][1]
                i = end
                continue
            if kind == "id" and text == "mod" and self.tok(i + 1)[0] == "id":
                name = self.tok(i + 1)[1]
                after = self.tok(i + 2)[1]
                if depth == 0:
                    self.crate.defs[scope].add(name)
                if test_attr:
                    i = self.skip_item(i)
                elif after == "{":
                    inner = scope + (name,)
                    self.crate.scopes[inner] = self.file_module
                    self.crate.defs.setdefault(inner, set())
                    sub_dir = child_dir / (path_attr if path_attr else name)
                    i = self.block(i + 3, inner, sub_dir)
                elif after == ";":
                    self.declare_file(scope + (name,), name, path_attr, child_dir)
                    i += 3
                else:
                    i += 1
                test_attr, path_attr = False, None
                continue
            if test_attr and kind == "id" and text not in ("pub", "crate", "in", "super", "self"):
                i = self.skip_item(i)  # a `#[cfg(test)]` item other than a module
                test_attr, path_attr = False, None
                continue
            if kind == "id" and text == "use":
                i = self.use(i, scope)
                test_attr, path_attr = False, None
                continue
            if kind == "id" and depth == 0 and self.tok(i + 1)[0] == "id":
                if text in ITEM_KEYWORDS and not (text == "const" and self.tok(i + 1)[1] in ("fn", "unsafe", "async", "extern")):
                    name = self.tok(i + 1)[1]
                    if text == "static" and name == "mut":
                        name = self.tok(i + 2)[1]
                    self.crate.defs[scope].add(name)
            if kind == "id" and text == "macro_rules" and self.tok(i + 1)[1] == "!" and depth == 0:
                self.crate.defs[scope].add(self.tok(i + 2)[1])
            if text in ("{", "}", ";") and kind == "p":
                test_attr, path_attr = False, None
                if text == "{":
                    depth += 1
                elif text == "}":
                    if depth == 0:
                        return i + 1
                    depth -= 1
                i += 1
                continue
            if kind == "id":
                self.crate.words.setdefault(scope, set()).add(text)
            if self.starts_path(i):
                path, i = self.read_path(i)
                if len(path) > 1:
                    self.crate.paths.append((scope, path))
                continue
            i += 1
        return i

    def declare_file(self, module: Scope, name: str, path_attr: str | None, child_dir: Path) -> None:
        if path_attr is not None:
            candidates = [self.file.parent / path_attr]
        else:
            candidates = [child_dir / f"{name}.rs", child_dir / name / "mod.rs"]
        for file in candidates:
            if file.is_file():
                nested = file.parent if file.name == "mod.rs" else file.parent / file.stem
                self.crate._file(module, file, nested)
                return
        raise SystemExit(f"{self.file}: module `{name}` declared, no file at {candidates[0]}")

    def starts_path(self, i: int) -> bool:
        """A path `a::b…` starts at token `i` (not the middle of one; `$crate::` included)."""
        kind, text = self.tok(i)
        if kind == "p" and text == "$":
            return self.tok(i + 1) == ("id", "crate") and self.tok(i + 2)[1] == "::"
        before = self.t[i - 1][1] if i > 0 else ""
        return kind == "id" and self.tok(i + 1)[1] == "::" and before not in ("::", "$")

    def read_path(self, i: int) -> tuple[list[str], int]:
        if self.tok(i)[1] == "$":
            i += 1
        path = [self.tok(i)[1]]
        i += 1
        while self.tok(i)[1] == "::" and self.tok(i + 1)[0] == "id":
            path.append(self.tok(i + 1)[1])
            i += 2
        return path, i

    def skip_group(self, i: int) -> int:
        """From an opening bracket at `i` to after its closing one."""
        depth = 0
        while i < len(self.t):
            kind, text = self.t[i]
            if kind == "p" and text in ("(", "[", "{"):
                depth += 1
            elif kind == "p" and text in (")", "]", "}"):
                depth -= 1
            i += 1
            if depth == 0:
                return i
        return i

    def skip_item(self, i: int) -> int:
        """From an item's keyword to after its `;` or its body's closing brace."""
        while i < len(self.t):
            kind, text = self.t[i]
            if kind == "p" and text in ("(", "["):
                i = self.skip_group(i)
            elif kind == "p" and text == "{":
                return self.skip_group(i)
            elif kind == "p" and text in (";", "}"):
                return i + (text == ";")
            else:
                i += 1
        return i

    def skip_to_scope_end(self, i: int, depth: int) -> int:
        while i < len(self.t):
            text = self.t[i][1] if self.t[i][0] == "p" else ""
            if text == "{":
                depth += 1
            elif text == "}":
                if depth == 0:
                    return i + 1
                depth -= 1
            i += 1
        return i

    def use(self, i: int, scope: Scope) -> int:
        j = i - 1
        if self.tok(j)[1] == ")":
            while j > 0 and self.tok(j)[1] != "(":
                j -= 1
            j -= 1
        public = j >= 0 and self.tok(j) == ("id", "pub")
        end = i + 1
        while end < len(self.t) and self.t[end][1] != ";":
            end += 1
        tree = [tx for _, tx in self.t[i + 1 : end]]
        if tree and tree[0] == "$":
            tree = tree[1:]
        for path, alias in expand_use(tree):
            self.crate.uses.append(Use(scope, path, alias, public))
        return end + 1


def expand_use(tree: list[str]) -> list[tuple[list[str], str | None]]:
    """Tokens of `a::{b, c::{d, e as f}, self, g::*}` -> (path, bound name) pairs:
    ([a,b],b) ([a,c,d],d) ([a,c,e],f) ([a],a) ([a,g,*],None). `as _` binds nothing."""
    out: list[tuple[list[str], str | None]] = []

    def walk(prefix: list[str], i: int) -> int:
        path = list(prefix)
        while i < len(tree):
            tx = tree[i]
            if tx == "::":
                i += 1
            elif tx == "{":
                i += 1
                while i < len(tree) and tree[i] != "}":
                    i = walk(path, i)
                    if i < len(tree) and tree[i] == ",":
                        i += 1
                return i + 1
            elif tx == "*":
                out.append((path + ["*"], None))
                return i + 1
            elif tx in (",", "}"):
                break
            elif tx == "as":
                alias = tree[i + 1] if i + 1 < len(tree) else "_"
                if path and path[-1] == "self":
                    path.pop()
                out.append((path, None if alias == "_" else alias))
                return i + 2
            else:
                path.append(tx)
                i += 1
        if path and path[-1] == "self":
            path.pop()
        if path and len(path) > len(prefix) or (path and tree[i - 1 : i] == ["self"]):
            out.append((path, path[-1]))
        return i

    walk([], 0)
    return out


class Graph:
    def __init__(self, crate: Crate):
        self.c = crate

    def absolute(self, scope: Scope, path: list[str], hops: int = 0) -> list[str] | None:
        """A path as written in `scope` as names from the crate root; None when it starts
        outside the crate (another crate, the prelude, a local name)."""
        if not path or hops > 32:
            return None
        head = path[0]
        if head == "crate":
            return path[1:]
        if head in ("super", "self"):
            base = list(scope)
            while path and path[0] in ("super", "self"):
                if path[0] == "super":
                    if not base:
                        return None
                    base.pop()
                path = path[1:]
            return base + path
        if scope + (head,) in self.c.scopes:
            return list(scope) + path
        use = self.c.bindings.get((scope, head))
        if use is not None and use.path != path[:1]:
            target = self.absolute(use.scope, use.path, hops + 1)
            return None if target is None else target + path[1:]
        return None

    def resolve(self, absolute: list[str], strict: bool = False, hops: int = 0) -> Scope | None:
        """The scope defining the item `absolute` names, `use`s followed. Unknown names stay
        with the scope reached (strict: None)."""
        scope: Scope = ()
        for i, name in enumerate(absolute):
            if name == "*":
                return scope
            if scope + (name,) in self.c.scopes:
                scope += (name,)
                continue
            if name in self.c.defs.get(scope, ()):
                return scope
            if hops < 32:
                use = self.c.bindings.get((scope, name))
                if use is not None:
                    target = self.absolute(use.scope, use.path)
                    if target is None:
                        return None  # re-exported from another crate
                    if target != absolute[: i + 1]:
                        return self.resolve(target + absolute[i + 1 :], strict, hops + 1)
                for glob in self.c.globs.get(scope, []):
                    base = self.absolute(glob.scope, glob.path[:-1])
                    if base is not None and base != list(scope):
                        found = self.resolve(base + absolute[i:], True, hops + 1)
                        if found is not None:
                            return found
            return None if strict else scope
        return scope

    def facade(self, use: Use, absolute: list[str]) -> bool:
        """A `pub use` of the module's own descendants that the module's own code never names
        (for a glob: any). A private `use` always counts: an import its module never names may
        still bring a trait's methods into scope."""
        if not use.public or absolute[: len(use.scope)] != list(use.scope):
            return False
        return use.alias is None or use.alias not in self.c.words.get(use.scope, ())

    def edges(self) -> dict[Scope, set[Scope]]:
        files = {self.c.scopes[s] for s in self.c.scopes}
        graph: dict[Scope, set[Scope]] = {m: set() for m in files}
        named = [(u.scope, u.path, u) for u in self.c.uses]
        named += [(scope, path, None) for scope, path in self.c.paths]
        for scope, path, use in named:
            absolute = self.absolute(scope, path)
            if absolute is None:
                continue
            if use is not None and self.facade(use, absolute):
                continue
            target = self.resolve(absolute)
            if target is None:
                continue
            source, target = self.c.scopes[scope], self.c.scopes[target]
            if target != source:
                graph[source].add(target)
        return graph


def crate_roots(crate_dir: Path) -> list[tuple[str, Path]]:
    src = crate_dir / "src"
    roots = [(crate_dir.name, src / "lib.rs")] if (src / "lib.rs").is_file() else []
    if (src / "main.rs").is_file():
        roots.append((crate_dir.name + (" (bin)" if roots else ""), src / "main.rs"))
    roots += [(f"{crate_dir.name} (bin {p.stem})", p) for p in sorted((src / "bin").glob("*.rs"))]
    return roots


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


def name(module: Scope) -> str:
    return "::".join(module) or "(crate root)"


def loops(crate_dir: Path) -> list[str]:
    """Each loop of the crate's module graph as printable lines."""
    out = []
    for crate_name, root in crate_roots(crate_dir):
        graph = Graph(Crate(crate_name).load(root)).edges()
        for component in strongly_connected(graph):
            members = set(component)
            out.append(f"{crate_name}: import loop among {', '.join(sorted(map(name, members)))}")
            out += [f"  {name(a)} -> {name(b)}" for a in sorted(members) for b in sorted(graph[a] & members)]
    return out


def main(argv: list[str]) -> int:
    dirs = [Path(a) for a in argv] or sorted(
        [p for p in (ROOT / "crates").iterdir() if (p / "src").is_dir()]
        + [p for p in [ROOT / "tests", ROOT / "fuzz"] if (p / "src").is_dir()]
    )
    count = 0
    for crate_dir in dirs:
        lines = loops(crate_dir)
        count += sum(1 for line in lines if not line.startswith(" "))
        if lines:
            print("\n".join(lines))
    if count:
        print(f"{count} import loop(s); modules in a crate must form a DAG (docs/ARCHITECTURE.md)")
        return 1
    print("no import loops")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
