"""The tiers: every entry of tests/slow.txt names a test file, function or case that exists (a stale
entry would silently move nothing), and the marking puts exactly the listed tests in the slow tier."""

import ast
import functools
import os
import re

from conftest import SLOW_LIST, _listed, slow_entries

TESTS = os.path.dirname(__file__)
ENTRY = re.compile(r"^tests/(test_\w+\.py)(?:::(test_\w+)(\[.+\])?)?$")


@functools.cache
def _functions(path):
    with open(path, encoding="utf-8") as stream:
        tree = ast.parse(stream.read())
    names = {node.name for node in ast.walk(tree) if isinstance(node, ast.FunctionDef)}
    for node in ast.walk(tree):  # tests made by a factory: test_a, test_b = make(...)
        if isinstance(node, ast.Assign):
            targets = [t for target in node.targets for t in ast.walk(target)]
            names |= {t.id for t in targets if isinstance(t, ast.Name)}
    return names


def test_every_slow_entry_names_an_existing_test():
    entries = slow_entries()
    assert entries, SLOW_LIST
    assert len(entries) == len(set(entries)), "duplicate entries"
    for entry in entries:
        match = ENTRY.match(entry)
        assert match, f"not a test file, function or case: {entry!r}"
        path = os.path.join(TESTS, match.group(1))
        assert os.path.isfile(path), entry
        if match.group(2):
            assert match.group(2) in _functions(path), entry


def test_listing_marks_files_functions_and_single_cases():
    entries = frozenset(["tests/test_a.py", "tests/test_b.py::test_f", "tests/test_c.py::test_g[2]"])
    assert _listed("tests/test_a.py::test_x[1-2]", entries)
    assert _listed("tests/test_b.py::test_f[3]", entries)
    assert _listed("tests/test_b.py::test_f", entries)
    assert not _listed("tests/test_b.py::test_f2", entries)
    assert _listed("tests/test_c.py::test_g[2]", entries)
    assert not _listed("tests/test_c.py::test_g[20]", entries)
    assert not _listed("tests/test_ab.py::test_x", entries)
