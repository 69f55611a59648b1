"""
Size limits of the package's source: modules, functions and classes a reader can hold.

No module over 800 lines, no function over 120, no class over 300.  The compiled kernel
(``ball_screw/kernel.py``: numba functions, one per equation block, inlined by hand for
speed) is exempt.  ``OVER_LIMIT`` lists the offenders still waiting for their split; the
test fails when one of them grows past the size it had, or no longer needs its entry.
"""

import ast
import pathlib

PACKAGE = pathlib.Path(__file__).resolve().parent.parent / "bb_friction_ros"
MAX_MODULE_LINES = 800
MAX_FUNCTION_LINES = 120
MAX_CLASS_LINES = 300
EXEMPT = {"ball_screw/kernel.py"}
# "path:name" -> lines it has now: it may shrink, not grow
OVER_LIMIT = {}


def offenders(root=PACKAGE, exempt=EXEMPT):
    """Return {"path" or "path:name": lines} of everything under ``root`` over its limit."""
    found = {}
    for path in sorted(root.rglob("*.py")):
        rel = path.relative_to(root).as_posix()
        if rel in exempt:
            continue
        source = path.read_text()
        if source.count("\n") > MAX_MODULE_LINES:
            found[rel] = source.count("\n")
        for node in ast.walk(ast.parse(source, filename=str(path))):
            limit = MAX_CLASS_LINES if isinstance(node, ast.ClassDef) else \
                MAX_FUNCTION_LINES if isinstance(node, (ast.FunctionDef,
                                                        ast.AsyncFunctionDef)) else None
            lines = node.end_lineno - node.lineno + 1 if limit else 0
            if limit and lines > limit:
                found[f"{rel}:{node.name}"] = lines
    return found


def test_modules_functions_and_classes_stay_within_their_size_limits():
    found = offenders()
    new = {k: v for k, v in found.items() if k not in OVER_LIMIT}
    assert not new, f"over the size limits (module {MAX_MODULE_LINES}, function " \
        f"{MAX_FUNCTION_LINES}, class {MAX_CLASS_LINES} lines): {new}"
    grown = {k: (found[k], v) for k, v in OVER_LIMIT.items() if k in found and found[k] > v}
    assert not grown, f"grew past their recorded size (now, recorded): {grown}"
    done = sorted(k for k in OVER_LIMIT if k not in found)
    assert not done, f"within the limits now: remove from OVER_LIMIT: {done}"


def test_the_size_check_finds_each_kind_of_offender(tmp_path):
    body = "    x = 1\n"
    (tmp_path / "ok.py").write_text("def f():\n" + body * (MAX_FUNCTION_LINES - 1))
    (tmp_path / "f.py").write_text("def f():\n" + body * MAX_FUNCTION_LINES)
    (tmp_path / "c.py").write_text("class C:\n" + "".join(
        f"    def m{i}(self):\n        return {i}\n" for i in range(MAX_CLASS_LINES // 2)))
    (tmp_path / "m.py").write_text("x = 1\n" * (MAX_MODULE_LINES + 1))
    assert offenders(tmp_path, exempt=()) == {"f.py:f": MAX_FUNCTION_LINES + 1,
                                              "c.py:C": MAX_CLASS_LINES + 1,
                                              "m.py": MAX_MODULE_LINES + 1}
