"""The code's layering, checked from the source alone: the harness's modules import each other without
a cycle and only downwards through the layers, and the C framework's files call each other one way."""
from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
HARNESS = ROOT / "harness"
FRAMEWORK = ROOT / "fmus" / "framework"

# Lowest first; a module may import from its own layer and the layers below it. Objects and FMUs
# share the bottom layer: an object's FMU is proven by running it (objects -> fmi) and the FMUs the
# project builds are the registry's objects (fmi -> objects), so only the modules must not cycle.
LAYERS = {
    "errors": 0, "archives": 0, "output": 0, "processes": 0, "interrupts": 0,
    "objects": 1, "fmi": 1,
    "cosim": 2,
    "studies": 3,
    "scene": 4, "view": 4,
    "cli": 5, "__main__": 5, "__init__": 5, "reference_pages": 5,
}


def module_name(path: Path) -> str:
    parts = path.relative_to(ROOT).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def layer_of(module: str) -> str:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "__init__"


def harness_modules() -> dict[str, Path]:
    return {module_name(path): path for path in sorted(HARNESS.rglob("*.py"))}


def imported_modules(module: str, path: Path, known: set[str]) -> set[str]:
    """The harness modules that `module` imports anywhere in its text (also inside functions)."""
    package = module if path.name == "__init__.py" else module.rpartition(".")[0]
    found = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                base = ".".join(anchor + ([base] if base else []))
            # `from package import module` names a module; `from module import name` the module
            names = [f"{base}.{alias.name}" if f"{base}.{alias.name}" in known else base for alias in node.names]
        else:
            continue
        found.update(name for name in names if name in known and name != module)
    return found


def import_graph() -> dict[str, set[str]]:
    modules = harness_modules()
    return {module: imported_modules(module, path, set(modules)) for module, path in modules.items()}


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    """One cycle as a path that starts and ends at the same node, or None."""
    done: set[str] = set()

    def visit(node: str, path: list[str]) -> list[str] | None:
        if node in path:
            return path[path.index(node):] + [node]
        if node in done:
            return None
        for target in sorted(graph.get(node, ())):
            cycle = visit(target, path + [node])
            if cycle:
                return cycle
        done.add(node)
        return None

    for node in sorted(graph):
        cycle = visit(node, [])
        if cycle:
            return cycle
    return None


def test_every_harness_module_has_a_layer():
    unplaced = sorted(m for m in harness_modules() if layer_of(m) not in LAYERS)
    assert not unplaced, f"place these in LAYERS: {unplaced}"


def test_harness_imports_have_no_cycle():
    graph = import_graph()
    assert sum(map(len, graph.values())) > 50  # the parser sees the imports at all
    cycle = find_cycle(graph)
    assert cycle is None, " -> ".join(cycle)


def test_harness_imports_go_down_the_layers():
    upward = [f"{source} -> {target}" for source, targets in import_graph().items() for target in sorted(targets)
              if LAYERS[layer_of(target)] > LAYERS[layer_of(source)]]
    assert not upward, "\n".join(upward)


def test_cycle_finder_finds_one():
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b", "c"}, "b": {"c"}, "c": set()}) is None


# ---------------------------------------------------------------- the C framework

C_KEYWORDS = {"if", "for", "while", "switch", "return", "sizeof"}


def c_functions(text: str) -> tuple[set[str], set[str]]:
    """The non-static functions a C file defines, and every identifier its bodies and initializers use."""
    text = re.sub(r"/\*.*?\*/|//[^\n]*", " ", text, flags=re.S)
    text = re.sub(r'"(\\.|[^"\\])*"|\'(\\.|[^\'\\])*\'', '""', text)
    text = "\n".join("" if line.lstrip().startswith("#") else line for line in text.split("\n"))
    defined, used = set(), set()
    depth, declaration, body = 0, [], []
    for char in text:
        if depth == 0:
            if char == "{":
                head = "".join(declaration)
                match = re.search(r"(\w+)\s*\((?:[^()]|\([^()]*\))*\)\s*$", head)
                if match and not re.search(r"\bstatic\b", head) and match.group(1) not in C_KEYWORDS:
                    defined.add(match.group(1))
                depth, declaration = 1, []
            elif char == ";":
                declaration = []
            else:
                declaration.append(char)
        else:
            body.append(char)
            depth += {"{": 1, "}": -1}.get(char, 0)
    used = set(re.findall(r"[A-Za-z_]\w*", "".join(body)))
    return defined, used


def framework_graph() -> dict[str, set[str]]:
    """File -> the framework files whose functions it uses."""
    files = {path.name: c_functions(path.read_text()) for path in sorted(FRAMEWORK.glob("*.c"))}
    owner = {name: file for file, (defined, _) in files.items() for name in defined}
    return {file: {owner[name] for name in used if name in owner and owner[name] != file}
            for file, (_, used) in files.items()}


def test_framework_files_call_each_other_one_way():
    graph = framework_graph()
    assert "core.c" in graph["fmi3_functions.c"] and "core.c" in graph["fmi2_functions.c"]
    assert "stepper.c" in graph["core.c"] and "instance.c" in graph["stepper.c"]
    cycle = find_cycle(graph)
    assert cycle is None, " -> ".join(cycle)


def test_c_reader_sees_definitions_and_uses():
    defined, used = c_functions("""
        static int helper(int a) { return a; }
        int visible(const double *x, void (*f)(int)) { /* call() */ return helper(x[0]) + other(1); }
        static const struct { const char *name; } TABLE[2] = {{"a{"}, {"b"}};
        """)
    assert defined == {"visible"}
    assert {"helper", "other"} <= used and "call" not in used
