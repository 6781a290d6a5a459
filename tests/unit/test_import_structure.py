"""
The packages' modules import, and import one another without circles, by design.

Every import counts, those inside functions too: an import moved into a function to
break a circle hides it from Python, not from a reader. A circle of modules is a
strongly connected component of the import graph with more than one module.
"""

import ast
import importlib
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[2] / 'ros2_ws' / 'src'
# The ROS-free packages (the unit tests' import path); the nodes' are the integration
# tests' (test_console_scripts starts every installed program).
ROS_FREE = ('vessel_description', 'vessel_physics', 'vessel_datasets', 'hybrid_models',
            'vessel_diagnosis')


def modules() -> dict[str, Path]:
    """Return every Python module of the ROS packages by dotted name."""
    found = {}
    for package in SRC.iterdir():
        if not (package / package.name / '__init__.py').is_file():
            continue
        for path in (package / package.name).rglob('*.py'):
            parts = path.relative_to(package).with_suffix('').parts
            found['.'.join(parts[:-1] if parts[-1] == '__init__' else parts)] = path
    return found


def import_graph(found: dict[str, Path]) -> dict[str, set[str]]:
    """Return module -> the project modules it imports anywhere in its text."""
    graph = {}
    for name, path in found.items():
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                targets |= {f'{node.module}.{a.name}' if f'{node.module}.{a.name}' in found
                            else node.module for a in node.names}
            elif isinstance(node, ast.Import):
                targets |= {a.name for a in node.names}
        graph[name] = set()
        for target in targets:
            while target and target not in found:
                target = target.rpartition('.')[0]
            if target and target != name:
                graph[name].add(target)
    return graph


def circles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Return the strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on_stack, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
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
            while not component or component[-1] != v:
                component.append(stack.pop())
                on_stack.discard(component[-1])
            if len(component) > 1:
                out.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_no_module_of_a_package_imports_itself_round_a_circle():
    found = modules()
    assert 'hybrid_models.training.train' in found and 'vessel_physics' in found
    assert circles(import_graph(found)) == []


@pytest.mark.parametrize('package', ROS_FREE)
def test_every_module_of_a_ros_free_package_imports(package):
    """A name moved to another module and still imported from the old one fails here."""
    names = sorted(n for n in modules() if n.split('.')[0] == package)
    assert names
    for name in names:
        importlib.import_module(name)


def test_a_circle_is_found_through_an_import_inside_a_function(tmp_path):
    a, b, c = (tmp_path / f'{n}.py' for n in 'abc')
    a.write_text('from pkg.b import x\n')
    b.write_text('def f():\n    from pkg.a import y\n')
    c.write_text('import pkg.a\n')
    found = {'pkg.a': a, 'pkg.b': b, 'pkg.c': c}
    assert circles(import_graph(found)) == [['pkg.a', 'pkg.b']]
