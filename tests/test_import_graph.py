"""The package's imports form no cycle, and the CLI only parses options and calls the library.
Walks every module's imports, module level and function level alike."""

import ast
from pathlib import Path

import dualpixel

PACKAGE = Path(dualpixel.__file__).parent


def module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def imports_of(path: Path, modules: set[str]) -> set[str]:
    found = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            base = node.module
            for alias in node.names:
                candidate = f"{base}.{alias.name}"
                found.add(candidate if candidate in modules else base)
        elif isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names)
    own = module_name(path)
    # importing a package runs its __init__: a module inside a package does not depend on it
    return {m for m in found if m in modules and m != own and not own.startswith(m + ".")}


def graph() -> dict[str, set[str]]:
    files = [p for p in PACKAGE.rglob("*.py")]
    modules = {module_name(p) for p in files}
    return {module_name(p): imports_of(p, modules) for p in files}


def test_no_import_cycle():
    edges = graph()
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(edges.get(node, ())):
            if state.get(nxt) == 1:
                cycle = [*stack[stack.index(nxt):], nxt]
                raise AssertionError("import cycle: " + " -> ".join(cycle))
            if nxt not in state:
                visit(nxt)
        stack.pop()
        state[node] = 2

    for node in sorted(edges):
        if node not in state:
            visit(node)


def test_library_never_imports_the_cli():
    for module, targets in graph().items():
        if not module.startswith("dualpixel.cli") and module != "dualpixel.__main__":
            assert not any(t.startswith("dualpixel.cli") for t in targets), module


def test_cli_modules_hold_no_image_processing():
    for path in (PACKAGE / "cli").glob("*.py"):
        tree = ast.parse(path.read_text())
        imported = {alias.name for node in ast.walk(tree) if isinstance(node, ast.Import)
                    for alias in node.names}
        imported |= {node.module for node in ast.walk(tree)
                     if isinstance(node, ast.ImportFrom) and node.module}
        processing = {"cv2", "numpy", "scipy", "scipy.ndimage", "skimage", "torch.nn.functional"}
        assert not imported & processing, (path.name, imported)


#: The package's layers, bottom to top: a module imports only from its own layer or below
#: (module level and function level alike). ``cameras`` and ``weights`` hold data files.
LAYERS = (
    ("names", "errors", "device", "memory", "progress", "filters", "parallel", "cameras",
     "examples"),
    ("io",),
    ("optics",),
    ("data",),
    ("synthesis",),
    ("models", "weights"),
    ("inference",),
    ("viz",),
    ("evaluation",),
    ("training",),
    ("calibration",),
    ("adaptation",),
    ("demo", "demo_data"),
    ("api",),
    ("cli", "__main__"),
)


def layer_of(module: str) -> int:
    part = module.split(".")[1] if "." in module else "api"
    for index, names in enumerate(LAYERS):
        if part in names:
            return index
    raise AssertionError(f"{module} is in no layer: add {part!r} to LAYERS")


def test_no_import_goes_up_the_layers():
    upward = sorted(f"{module} -> {target}" for module, targets in graph().items()
                    if module != "dualpixel" for target in targets
                    if target != "dualpixel" and layer_of(target) > layer_of(module))
    assert not upward, "imports that go up the layers:\n" + "\n".join(upward)
