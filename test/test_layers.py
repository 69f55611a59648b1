"""
The layers of bb_friction_ros import downward only, and nothing imports in a circle.

Every import is found in the source (AST), inside functions too: a lazy import is still an
edge.  docs/architecture.md describes the same layers; a new top-level module must be given
one here (and there).
"""

import ast
import pathlib

import pytest

PACKAGE = "bb_friction_ros"
ROOT = pathlib.Path(__file__).resolve().parent.parent / PACKAGE

# Lowest first; a module may import from its own layer or below.
LAYERS = {
    1: {"config", "contact", "paper", "compiled", ""},   # "": the package's __init__
    2: {"linear_bearing", "ball_screw", "empirical_terms", "model_file", "acceleration"},
    3: {"runner", "live", "bags", "interface", "node_parameters", "feedforward", "schedule",
        "inputs", "look_ahead", "friction_sign", "bag_types", "bag_writer", "alignment",
        "live_health", "drive"},
    4: {"replay", "replay_outputs", "node", "ros_inputs", "node_entry", "harness", "pytest_plugin",
        "trajectories", "planned"},
    5: {"discrepancy", "sweep", "demo", "reproduce", "servo"},
    6: {"cli", "cli_flags"},
}
# Below this layer nothing may import ROS: the physics core and the runner run without it.
# (config.bundled_config may ask ament_index_python, a plain-Python file index, where the
# installed share directory is; it works without it.)
FIRST_ROS_LAYER = 4
ROS_MODULES = ("rclpy", "rcl_interfaces", "builtin_interfaces", "std_msgs", "sensor_msgs",
               "geometry_msgs", "diagnostic_msgs", "bb_friction_msgs", "trajectory_msgs")


def component(module):
    """
    Return the unit a module belongs to: its top-level module or sub-package.

    A sub-package's ``cli.py`` (``ball_screw.cli``...) is a unit of its own in layer 6: it
    registers ``bb-friction`` sub-commands, like ``cli.py``, and may use any layer.  Kept
    beside the package it drives rather than moved, so the package's CLI stays with it.
    """
    parts = module.split(".")[1:]
    if len(parts) >= 2 and parts[-1] == "cli":
        return ".".join(parts)
    return parts[0] if parts else ""


def layer(module):
    """Return the layer of a module of the package, or None when it has none."""
    unit = component(module)
    if unit.endswith(".cli"):
        return 6
    for number, units in LAYERS.items():
        if unit in units:
            return number
    return None


def module_name(path, root):
    rel = path.relative_to(root.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join(parts)


def imports(path, module, modules):
    """Return [(imported module of the package or external top-level name, line)]."""
    tree = ast.parse(path.read_text(), filename=str(path))
    is_package = path.name == "__init__.py"
    found = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found += [(alias.name, node.lineno) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = module.split(".")
                anchor = anchor[: len(anchor) - node.level + (1 if is_package else 0)]
                base = ".".join(anchor + ([base] if base else []))
            for alias in node.names:
                full = f"{base}.{alias.name}"
                found.append((full if full in modules else base, node.lineno))
    return found


def import_graph(root):
    """Return ({module: path}, {module: {imported module: line}}, {module: {external}})."""
    paths = {module_name(p, root): p for p in sorted(root.rglob("*.py"))}
    edges, external = {}, {}
    for module, path in paths.items():
        edges[module], external[module] = {}, set()
        for name, line in imports(path, module, paths):
            if name == root.name or name.startswith(root.name + "."):
                while name not in paths:          # a name inside a module: the module
                    name = name.rpartition(".")[0]
                if name != module:
                    edges[module].setdefault(name, line)
            else:
                external[module].add(name.split(".")[0])
    return paths, edges, external


def cycles(graph):
    """Return the strongly connected components with more than one node (Tarjan)."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            scc = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                scc.append(w)
                if w == v:
                    break
            if len(scc) > 1:
                out.append(sorted(scc))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def problems(root):
    """Return every layer violation of the package at ``root``, one line each."""
    paths, edges, external = import_graph(root)
    out = []
    for module in paths:
        if layer(module) is None:
            out.append(f"{module}: no layer (give it one in test_layers.py and "
                       "docs/architecture.md)")
    for module, targets in edges.items():
        for target, line in targets.items():
            lo, hi = layer(module), layer(target)
            if lo is not None and hi is not None and hi > lo:
                out.append(f"{module}:{line} imports {target}: layer {lo} imports upward "
                           f"from layer {hi}")
        if layer(module) is not None and layer(module) < FIRST_ROS_LAYER:
            for name in sorted(external[module] & set(ROS_MODULES)):
                out.append(f"{module} imports {name}: ROS below layer {FIRST_ROS_LAYER}")
    for scc in cycles(edges):
        out.append(f"module cycle: {' -> '.join(scc)}")
    units = {}
    for module, targets in edges.items():
        for target in targets:
            if component(target) != component(module):
                units.setdefault(component(module), set()).add(component(target))
    for scc in cycles(units):
        out.append(f"package cycle: {' -> '.join(scc)}")
    return out


def test_layers_import_downward_only_and_without_cycles():
    found = problems(ROOT)
    assert not found, "\n".join(found)


def test_every_module_has_a_layer():
    paths, _, _ = import_graph(ROOT)
    assert all(layer(m) is not None for m in paths)
    assert len(paths) > 40                  # the walk found the package


def _fake_package(tmp_path, files):
    root = tmp_path / PACKAGE
    for name, text in {"__init__.py": "", **files}.items():
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(text)
    return root


@pytest.mark.parametrize("files,needle", [
    ({"config.py": "def f():\n    from bb_friction_ros.runner import x\n",
      "runner.py": "x = 1\n"},
     "bb_friction_ros.config:2 imports bb_friction_ros.runner: layer 1 imports upward"),
    ({"runner.py": "from bb_friction_ros import bags\n",
      "bags.py": "def f():\n    import bb_friction_ros.runner\n"},
     "module cycle: bb_friction_ros.bags -> bb_friction_ros.runner"),
    ({"discrepancy/__init__.py": "", "discrepancy/data.py": "from ..runner import x\n",
      "runner.py": "from bb_friction_ros.discrepancy.data import y\n"},
     "layer 3 imports upward from layer 5"),
    ({"ball_screw/__init__.py": "", "ball_screw/b.py": "",
      "ball_screw/a.py": "from bb_friction_ros.model_file import f\n",
      "model_file.py": "from bb_friction_ros.ball_screw.b import g\n"},
     "package cycle: ball_screw -> model_file"),
    ({"runner.py": "import rclpy\n"}, "bb_friction_ros.runner imports rclpy"),
    ({"gadget.py": ""}, "bb_friction_ros.gadget: no layer"),
])
def test_the_check_finds_what_it_must(tmp_path, files, needle):
    """The checker itself: upward imports (also inside functions), cycles, ROS, no layer."""
    assert any(needle in p for p in problems(_fake_package(tmp_path, files))), \
        problems(_fake_package(tmp_path, files))


def test_sub_package_cli_is_layer_6():
    assert layer("bb_friction_ros.sweep.cli") == 6 and layer("bb_friction_ros.sweep.spec") == 5
