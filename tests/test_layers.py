"""Imports run down the layers only, never up, not even inside a function.

Every module of the package is parsed (not imported), and every ``import`` in it,
at the top or inside a function, is checked against the layer order:
errors and the runtime floor (processes, signals, files, the pool, the cache),
physics, bodies, propagation, optimisation, app, bench.
"""

import ast

import pytest

from conftest import REPO

PACKAGE = REPO / "esail_opt"
#: Layer of each part of the package, lowest first.
LAYERS = {"errors": 0, "runtime": 0, "physics": 1, "bodies": 2, "propagation": 3,
          "optimisation": 4, "app": 5, "bench": 6}


def _layer(dotted):
    """Layer of a module ``esail_opt.<part>...``; None outside the layered parts."""
    parts = dotted.split(".")
    if parts[0] != "esail_opt" or len(parts) < 2:
        return None
    return LAYERS.get(parts[1])


def _imports(path, root=REPO):
    """(line, module) of every import in the file under ``root``, relative ones resolved."""
    module = ".".join(path.relative_to(root).with_suffix("").parts)
    package = module if path.name == "__init__.py" else module.rsplit(".", 1)[0]
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield node.lineno, alias.name
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            if base == "esail_opt" or (node.level and not node.module):
                # ``from esail_opt import bench``: the names are the modules.
                for alias in node.names:
                    yield node.lineno, f"{base}.{alias.name}"
            else:
                yield node.lineno, base


#: The modules with a layer (the package's ``__init__`` is the public facade of
#: ``import esail_opt as eo``, above every layer, and is not one of them).
MODULES = sorted(p for p in PACKAGE.rglob("*.py")
                 if _layer(".".join(p.relative_to(REPO).with_suffix("").parts)) is not None)


def test_the_walk_sees_every_layer():
    seen = {_layer(".".join(p.relative_to(REPO).with_suffix("").parts)) for p in MODULES}
    assert seen == set(LAYERS.values())


@pytest.mark.parametrize("path", MODULES, ids=lambda p: str(p.relative_to(PACKAGE)))
def test_no_import_runs_upward(path):
    own = _layer(".".join(path.relative_to(REPO).with_suffix("").parts))
    upward = [f"line {line}: {name}" for line, name in _imports(path)
              if (_layer(name) or 0) > own]
    assert upward == []


def test_the_check_sees_an_upward_import_inside_a_function(tmp_path):
    fake = tmp_path / "esail_opt" / "physics" / "fake.py"
    fake.parent.mkdir(parents=True)
    fake.write_text("def f():\n    from esail_opt import bench\n    from ..app import cli\n"
                    "    import esail_opt.optimisation.scan\n")
    names = [name for _, name in _imports(fake, root=tmp_path)]
    assert names == ["esail_opt.bench", "esail_opt.app", "esail_opt.optimisation.scan"]
    assert [_layer(name) for name in names] == [6, 5, 4]
