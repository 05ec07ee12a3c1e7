"""The package's layers (docs/architecture.md): imports only go down, no cycles, rooms stay small.

Every ``import`` counts, including the lazy ones inside functions: a lazy import upward is
still an upward dependency.
"""

import ast
import os
import subprocess
import sys
from pathlib import Path

PKG = Path(__file__).resolve().parents[1] / "monovo_cli"

# lowest first; a module may import from its own folder and from lower ranks only
LAYERS = {
    "errors": 0, "version": 0,
    "geometry": 1,
    "image": 2,
    "core": 3,
    "mapping": 4, "evaluation": 4,  # siblings: after the run, and against ground truth
    "io": 5,
    "viz": 6, "synth": 6,  # siblings: neither imports the other
    "pipeline": 7,
    "cli": 8,
    "__main__": 9,  # python -m monovo_cli: calls the CLI
    "__init__": 9,  # the package's front door: re-exports the library entry point lazily
}
MAX_LINES = 400
LONG_MARK = "Long module:"  # a module above MAX_LINES says why at its top, after this mark
HARD_MAX_LINES = 500  # no module above this, whatever its reason: split it into rooms
CONTRACT_FILE = "SPEC.md"  # the contract's file, outside the package: never named in it


def _modules():
    paths = sorted(PKG.rglob("*.py"))
    assert paths, f"no modules under {PKG}"
    for path in paths:
        rel = path.relative_to(PKG).with_suffix("")
        yield ".".join(("monovo_cli",) + rel.parts), path


def _room(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def _imports(module: str, path: Path) -> set[str]:
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            if node.module == "monovo_cli":  # from monovo_cli import x: x is a module or a name
                out |= {f"monovo_cli.{a.name}" if (PKG / a.name).exists() or (PKG / f"{a.name}.py").exists()
                        else "monovo_cli" for a in node.names}
            elif node.module.startswith("monovo_cli."):
                out.add(node.module)
        elif isinstance(node, ast.ImportFrom) and node.level:
            raise AssertionError(f"{module}: relative import; the package uses absolute ones")
        elif isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.startswith("monovo_cli.")}
    return out


def _graph():
    return {m: _imports(m, p) for m, p in _modules()}


def test_every_room_has_a_rank():
    assert {_room(m) for m, _ in _modules()} <= set(LAYERS)


def test_imports_only_go_down():
    bad = []
    for mod, deps in _graph().items():
        here = _room(mod)
        for dep in deps:
            there = _room(dep)
            if there == here:
                continue
            if LAYERS[there] >= LAYERS[here]:
                bad.append(f"{mod} -> {dep}")
    assert not bad, "imports upward or sideways:\n" + "\n".join(bad)


def test_no_import_cycle():
    graph = {m: {d for d in deps if d in dict(_modules())} for m, deps in _graph().items()}
    state: dict[str, int] = {}

    def visit(node, stack):
        state[node] = 1
        for nxt in graph.get(node, ()):
            if state.get(nxt) == 1:
                raise AssertionError("import cycle: " + " -> ".join(stack[stack.index(nxt):] + [nxt]))
            if nxt not in state:
                visit(nxt, stack + [nxt])
        state[node] = 2

    for m in graph:
        if m not in state:
            visit(m, [m])


def test_long_modules_say_why():
    long = [f"{m} ({n} lines)" for m, p in _modules()
            if (n := len(p.read_text().splitlines())) > MAX_LINES
            and LONG_MARK not in (ast.get_docstring(ast.parse(p.read_text())) or "")]
    assert not long, f"above {MAX_LINES} lines without '{LONG_MARK} <why>' in the docstring: {long}"


def test_no_module_is_over_the_hard_limit():
    """A reason lets a module pass MAX_LINES, never HARD_MAX_LINES: a longer one is split."""
    long = [f"{m} ({n} lines)" for m, p in _modules()
            if (n := len(p.read_text().splitlines())) > HARD_MAX_LINES]
    assert not long, f"above {HARD_MAX_LINES} lines: {long}"


def test_the_package_names_no_contract_file():
    """The package names the contract by its content (the init.yaml convention, the CSV
    columns), never by the file that holds it, which is not shipped with it."""
    files = [p for p in PKG.rglob("*") if p.is_file() and "__pycache__" not in p.parts
             and p.suffix not in (".pyc", ".pyo")]
    assert any(p.suffix == ".py" for p in files), f"no modules under {PKG}"
    bad = [f"{p.relative_to(PKG)}:{i}" for p in files
           for i, line in enumerate(p.read_bytes().decode("utf-8", "replace").splitlines(), 1)
           if CONTRACT_FILE in line]
    assert not bad, f"{CONTRACT_FILE} named in: {bad}"


def test_the_core_does_no_io_and_no_cli():
    """Below the pipeline nothing imports click or tqdm (the pure core, thin edge)."""
    bad = []
    for mod, path in _modules():
        if LAYERS[_room(mod)] >= LAYERS["pipeline"]:
            continue
        for node in ast.walk(ast.parse(path.read_text())):
            names = ([a.name for a in node.names] if isinstance(node, ast.Import)
                     else [node.module or ""] if isinstance(node, ast.ImportFrom) else [])
            bad += [f"{mod}: {n}" for n in names if n.split(".")[0] in ("click", "tqdm")]
    assert not bad, bad


CORE_ROOMS = ("estimator", "plane", "recovery")
MAX_CORE_MODULES = 8


def test_core_is_in_rooms():
    """core/ keeps the sequence loop at its top and its jobs in rooms of their own."""
    top = sorted(p.stem for p in (PKG / "core").glob("*.py") if p.stem != "__init__")
    assert len(top) <= MAX_CORE_MODULES, f"core/ has {len(top)} modules at its top: {top}"
    for room in CORE_ROOMS:
        assert (PKG / "core" / room / "__init__.py").is_file(), f"core/{room}/ is missing"
    assert (PKG / "mapping").is_dir() and (PKG / "evaluation").is_dir()


def test_the_estimator_stands_alone():
    """core/estimator/ (one frame against one keyframe) needs no other part of the core but
    the options: the plane filter and the recovery build on it, never the other way."""
    bad = []
    for mod, deps in _graph().items():
        if not mod.startswith("monovo_cli.core.estimator"):
            continue
        bad += [f"{mod} -> {d}" for d in deps if d.startswith("monovo_cli.core.")
                and not d.startswith("monovo_cli.core.estimator") and d != "monovo_cli.core.options"]
    assert not bad, bad


def test_the_options_load_neither_numpy_nor_opencv():
    """Building tracking options (the command line, a batch worker before it limits its
    threads) imports the standard library only."""
    check = ("import sys, monovo_cli.core.options; "
             "loaded = sorted({'numpy', 'cv2'} & set(sys.modules)); "
             "assert not loaded, loaded")
    run = subprocess.run([sys.executable, "-c", check], cwd=PKG.parent, capture_output=True,
                         text=True, env={**os.environ, "PYTHONPATH": str(PKG.parent)})
    assert run.returncode == 0, run.stderr
