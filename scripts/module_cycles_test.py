#!/usr/bin/env python3
"""Tests of scripts/module_cycles.py on small made-up crates: each case writes a crate's
sources and checks the loops (or the edges) the checker finds.

Usage: scripts/module_cycles_test.py   (python3 -m unittest also finds it)
"""

from __future__ import annotations

import sys
import tempfile
import textwrap
import unittest
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import module_cycles  # noqa: E402


def crate(files: dict[str, str]) -> Path:
    root = Path(tempfile.mkdtemp(prefix="module-cycles-test-")) / "demo"
    for name, text in files.items():
        path = root / "src" / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(textwrap.dedent(text), encoding="utf-8")
    return root


def edges(files: dict[str, str]) -> set[tuple[str, str]]:
    """Every edge of the crate's graph as (from, to) names."""
    (crate_name, root_file), *_ = module_cycles.crate_roots(crate(files))
    graph = module_cycles.Graph(module_cycles.Crate(crate_name).load(root_file)).edges()
    name = module_cycles.name
    return {(name(a), name(b)) for a, targets in graph.items() for b in targets}


class Edges(unittest.TestCase):
    def test_use_groups_nested_and_renamed(self):
        found = edges({
            "lib.rs": "mod a; mod b; mod c; mod d;",
            "a.rs": "use crate::{b::{self, X as Y}, c::Z};",
            "b.rs": "pub struct X;",
            "c.rs": "pub struct Z;",
            "d.rs": "",
        })
        self.assertEqual(found, {("a", "b"), ("a", "c")})

    def test_inline_paths_in_code_types_and_macros(self):
        found = edges({
            "lib.rs": "mod a; mod b; mod c; mod d;",
            "a.rs": "fn f() -> u8 { crate::b::g() }",
            "b.rs": "pub fn g() -> u8 { 1 }\nfn h(x: Vec<super::c::T>) {}",
            "c.rs": "pub struct T;\nmacro_rules! m { () => { $crate::d::k() } }",
            "d.rs": "pub fn k() {}",
        })
        self.assertEqual(found, {("a", "b"), ("b", "c"), ("c", "d")})

    def test_self_super_and_child_paths(self):
        found = edges({
            "lib.rs": "mod p;",
            "p/mod.rs": "mod x; mod y;\npub struct Top;\nfn f() { x::g() }",
            "p/x.rs": "pub fn g() {}\nfn h() { super::y::k(); self::g(); }",
            "p/y.rs": "pub fn k() {}\nuse super::super::p::Top;",
        })
        self.assertEqual(found, {("p", "p::x"), ("p::x", "p::y"), ("p::y", "p")})

    def test_inline_module_super_is_its_file(self):
        # `super` inside `mod inner { }` of a.rs is a.rs itself, not the crate root.
        found = edges({
            "lib.rs": "mod a; mod b;\npub struct Root;",
            "a.rs": "pub struct A;\nmod inner { use super::A; fn f() { super::super::b::g() } }",
            "b.rs": "pub fn g() {}",
        })
        self.assertEqual(found, {("a", "b")})

    def test_reexports_lead_to_the_defining_module(self):
        found = edges({
            "lib.rs": "mod a; mod b; mod error;\npub use error::Error;\nuse b::Helper;",
            "error.rs": "pub enum Error {}",
            "a.rs": "use crate::Error;\nfn f() -> crate::Error { todo!() }\nuse super::Helper;",
            "b.rs": "pub struct Helper;",
        })
        # The root's `pub use` is a facade; its private import is an edge of its own (an
        # import never named may bring a trait's methods), `a`'s path through it leads to `b`.
        self.assertEqual(found, {("a", "error"), ("a", "b"), ("(crate root)", "b")})

    def test_glob_reexports(self):
        found = edges({
            "lib.rs": "mod a; mod kinds;\npub use kinds::*;",
            "kinds.rs": "pub struct Kind;",
            "a.rs": "fn f(_: crate::Kind) {}",
        })
        self.assertEqual(found, {("a", "kinds")})

    def test_facade_counts_when_the_parent_uses_it(self):
        files = {"lib.rs": "mod a;\npub use a::A;\npub struct R;", "a.rs": "pub struct A;\nuse crate::R;"}
        self.assertEqual(edges(files), {("a", "(crate root)")})
        files["lib.rs"] += "\nfn f(_: A) {}"
        self.assertEqual(edges(files), {("a", "(crate root)"), ("(crate root)", "a")})

    def test_pub_use_of_a_sibling_is_an_edge(self):
        found = edges({"lib.rs": "mod a; mod b;", "a.rs": "pub use crate::b::B;", "b.rs": "pub struct B;"})
        self.assertEqual(found, {("a", "b")})

    def test_test_code_and_text_are_left_out(self):
        found = edges({
            "lib.rs": "mod a; mod b;\n#[cfg(test)]\nmod tests;",
            "tests.rs": "use crate::a::A;",
            "a.rs": """
                pub struct A;
                // crate::b::B in a comment
                /* crate::b::B /* nested */ crate::b::B */
                const S: &str = "crate::b::B";
                const R: &str = r#"crate::b::B "quoted" "#;
                const Q: char = '"';
                fn f<'a>(x: &'a str) -> &'a str { x }
                #[cfg(test)]
                fn helper() { crate::b::g() }
                #[cfg(test)]
                use crate::b::B;
                #[cfg(test)]
                mod tests { use crate::b::B; }
            """,
            "b.rs": "pub struct B;\npub fn g() {}\nuse crate::a::A;",
        })
        self.assertEqual(found, {("b", "a")})

    def test_external_paths_are_not_edges(self):
        found = edges({
            "lib.rs": "mod a; mod fmt;",
            "fmt.rs": "",
            "a.rs": "use std::fmt;\nuse serde::Serialize;\nfn f() { std::fmt::write; other_crate::x(); }",
        })
        self.assertEqual(found, set())

    def test_path_attribute(self):
        found = edges({
            "lib.rs": '#[path = "elsewhere/impl_a.rs"]\nmod a;\nmod b;',
            "elsewhere/impl_a.rs": "use crate::b::B;",
            "b.rs": "pub struct B;",
        })
        self.assertEqual(found, {("a", "b")})


class Loops(unittest.TestCase):
    def test_a_loop_is_reported_with_its_edges(self):
        root = crate({
            "lib.rs": "mod a; mod b; mod c;",
            "a.rs": "use crate::b::B;\npub struct A;",
            "b.rs": "pub struct B;\nfn f() { crate::c::g() }",
            "c.rs": "pub fn g() -> crate::a::A { todo!() }",
        })
        self.assertEqual(module_cycles.loops(root), [
            "demo: import loop among a, b, c", "  a -> b", "  b -> c", "  c -> a",
        ])
        self.assertEqual(module_cycles.main([str(root)]), 1)

    def test_a_dag_passes(self):
        root = crate({"lib.rs": "mod a; mod b;\npub use a::A;", "a.rs": "use crate::b::B;\npub struct A;", "b.rs": "pub struct B;"})
        self.assertEqual(module_cycles.loops(root), [])
        self.assertEqual(module_cycles.main([str(root)]), 0)


if __name__ == "__main__":
    unittest.main()
