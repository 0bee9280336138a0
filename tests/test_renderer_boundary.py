"""The renderer's boundary: Mitsuba and Dr.Jit are imported only inside ``sparselt/rendering/mitsuba/``.

Everything else works on arrays, so it can be tested without rendering; and
storage writes images without importing the renderer (issue 34).
"""

import ast
import pathlib
import subprocess
import sys

import pytest

SOURCE = pathlib.Path(__file__).resolve().parents[1] / "src" / "sparselt"
RENDERER = SOURCE / "rendering" / "mitsuba"
ENGINE_MODULES = {"mitsuba", "drjit"}


def _imported_modules(path):
    """``(line, absolute module name)`` of every import in a source file; relative ones resolved in the package."""
    package = list(path.relative_to(SOURCE.parent).with_suffix("").parts)[:-1]  # a module's or __init__'s package
    found = []
    for node in ast.walk(ast.parse(path.read_text(), filename=str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, alias.name) for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package[:len(package) - node.level + 1]
                module = ".".join(base + ([node.module] if node.module else []))
            else:
                module = node.module
            found += [(node.lineno, module)]
            found += [(node.lineno, f"{module}.{alias.name}") for alias in node.names]
    return found


def _sources():
    return sorted(SOURCE.rglob("*.py"))


def test_the_walk_sees_every_module_and_resolves_relative_imports():
    files = _sources()
    assert SOURCE / "cli.py" in files and RENDERER / "runtime.py" in files and len(files) > 50
    imported = {name for _, name in _imported_modules(RENDERER / "scene.py")}
    assert "sparselt.rendering.mitsuba.runtime" in imported  # from .runtime
    # from ..scenes: two levels up, not the renderer package's own (there is none)
    assert "sparselt.rendering.scenes" in imported and "sparselt.rendering.mitsuba.scenes" not in imported
    imported = {name for _, name in _imported_modules(RENDERER / "scene_dictionaries.py")}
    assert "sparselt.rendering.scenes" in imported
    assert {name for _, name in _imported_modules(RENDERER / "runtime.py")} >= {"drjit", "mitsuba"}


def test_mitsuba_and_drjit_are_imported_only_inside_the_renderer_package():
    offenders = []
    for path in _sources():
        if RENDERER in path.parents:
            continue
        for line, name in _imported_modules(path):
            if name.split(".")[0] in ENGINE_MODULES:
                offenders.append(f"{path.relative_to(SOURCE.parent)}:{line} imports {name}")
    assert not offenders, "Mitsuba / Dr.Jit outside sparselt/rendering/mitsuba/:\n" + "\n".join(offenders)


@pytest.mark.parametrize("module", ["storage", "image_io", "images"])
def test_image_and_storage_code_does_not_import_the_renderer(module):
    paths = sorted((SOURCE / module).rglob("*.py")) if (SOURCE / module).is_dir() else [SOURCE / f"{module}.py"]
    for path in paths:
        for line, name in _imported_modules(path):
            assert not name.startswith("sparselt.rendering.mitsuba"), f"{path.name}:{line} imports {name}"


def test_importing_the_renderer_package_and_the_cli_starts_neither_mitsuba_nor_drjit():
    """The CLI reads the variants from the renderer's runtime; Mitsuba starts only in ``initialize``."""
    code = ("import sys, sparselt.cli, sparselt.rendering.mitsuba as renderer; "
            "assert renderer.DEFAULT_VARIANT in renderer.SUPPORTED_VARIANTS; "
            "print(sorted(name for name in ('mitsuba', 'drjit') if name in sys.modules))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"
