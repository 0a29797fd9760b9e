"""The package's layers, checked from the source: no import cycle between its folders nor
between its modules, Ray only where actors are defined and driven, and a plain Sim env that
pulls in neither Ray nor torch."""

from __future__ import annotations

import ast
import sys
from collections import defaultdict
from collections.abc import Container
from pathlib import Path

from robogym_ray import children

PACKAGE = Path(__file__).resolve().parents[1] / "robogym_ray"
RAY_ALLOWED = {"distributed", "training", "sweep"}
"""Folders that may import Ray: the actor definitions, the driver that runs them, and the
sweep that runs drivers as Ray Tune trials."""


def imports(path: Path) -> set[str]:
    """Every absolute import in ``path``, lazy (inside functions) ones included."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text())):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            out.add(node.module)
            if node.module == "robogym_ray":  # `from robogym_ray import envs`
                out.update(f"robogym_ray.{alias.name}" for alias in node.names)
    return out


def unit(module: str) -> str:
    """The layer a module belongs to: its folder under robogym_ray/, or a top-level module."""
    parts = module.split(".")
    return parts[1] if len(parts) > 1 else "robogym_ray"


def folder_graph() -> dict[str, set[str]]:
    graph: dict[str, set[str]] = defaultdict(set)
    for path in PACKAGE.rglob("*.py"):
        rel = path.relative_to(PACKAGE.parent).with_suffix("")
        source = unit(".".join(rel.parts))
        if source == "__init__":
            continue  # robogym_ray/__init__.py registers the envs; it is the package itself
        for name in imports(path):
            if name.startswith("robogym_ray.") and unit(name) != source:
                graph[source].add(unit(name))
    return graph


def find_cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}  # 1: on the stack, 2: done

    def visit(node: str, stack: list[str]) -> list[str] | None:
        state[node] = 1
        for nxt in sorted(graph.get(node, ())):
            if state.get(nxt) == 1:
                return [*stack[stack.index(nxt) :], nxt] if nxt in stack else [node, nxt]
            if nxt not in state and (cycle := visit(nxt, [*stack, nxt])):
                return cycle
        state[node] = 2
        return None

    for start in sorted(graph):
        if start not in state and (cycle := visit(start, [start])):
            return cycle
    return None


def test_no_import_cycle_between_folders() -> None:
    graph = folder_graph()
    assert {"envs", "learner", "experience", "distributed", "training"} <= set(graph)
    assert find_cycle(graph) is None, " -> ".join(find_cycle(graph) or [])


def module_name(path: Path) -> str:
    """``robogym_ray/training/setup.py`` -> ``robogym_ray.training.setup``; a package's
    ``__init__.py`` is the package."""
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def module_graph() -> dict[str, set[str]]:
    """Which of the package's modules each imports, lazy imports included: an import names the
    longest module it starts with (``from robogym_ray.training import setup`` the module
    ``setup``, ``from robogym_ray.learner.checkpoint import RUN_CHECKPOINT`` ``checkpoint``)."""
    paths = {module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph: dict[str, set[str]] = {}
    for name, path in paths.items():
        targets = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                wanted = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
                wanted = [f"{node.module}.{alias.name}" for alias in node.names]
            else:
                continue
            found = (longest_module(full, paths) for full in wanted)
            targets.update(m for m in found if m is not None and m != name)
        graph[name] = targets
    return graph


def longest_module(name: str, modules: Container[str]) -> str | None:
    """The longest of ``modules`` that the dotted ``name`` starts with."""
    parts = name.split(".")
    for n in range(len(parts), 0, -1):
        if ".".join(parts[:n]) in modules:
            return ".".join(parts[:n])
    return None


def import_loops(graph: dict[str, set[str]]) -> list[list[str]]:
    """The graph's loops: each set of nodes that reach one another (a strongly connected
    component of more than one node), sorted."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    loops: list[list[str]] = []

    def visit(node: str) -> None:  # Tarjan's algorithm
        index[node] = low[node] = len(index)
        stack.append(node)
        for nxt in sorted(graph.get(node, ())):
            if nxt not in index:
                visit(nxt)
                low[node] = min(low[node], low[nxt])
            elif nxt in stack:
                low[node] = min(low[node], index[nxt])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                loops.append(sorted(component))

    for start in sorted(graph):
        if start not in index:
            visit(start)
    return sorted(loops)


def test_no_import_loop_between_modules() -> None:
    """No module imports one that imports it back, inside a folder too (``training/api.py`` and
    ``training/command.py`` once did): each loop is listed by its modules."""
    graph = module_graph()
    assert "robogym_ray.training.setup" in graph["robogym_ray.training.program"]
    loops = import_loops(graph)
    assert loops == [], "\n".join(" <-> ".join(loop) for loop in loops)


def test_the_loop_finder_finds_every_loop() -> None:
    graph = {"a": {"b"}, "b": {"a", "c"}, "c": {"d"}, "d": {"c"}, "e": {"a"}}
    assert import_loops(graph) == [["a", "b"], ["c", "d"]]
    assert import_loops({"a": {"b"}, "b": set()}) == []


def test_the_cycle_finder_finds_a_cycle() -> None:
    assert find_cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert find_cycle({"a": {"b"}, "b": set()}) is None


def test_only_distributed_and_training_import_ray() -> None:
    offenders = sorted(
        str(path.relative_to(PACKAGE))
        for path in PACKAGE.rglob("*.py")
        if any(name.split(".")[0] == "ray" for name in imports(path))
        and path.relative_to(PACKAGE).parts[0] not in RAY_ALLOWED
    )
    assert offenders == []


def test_the_low_layers_stay_low() -> None:
    graph = folder_graph()
    leaves = {"errors", "text"}  # import nothing of the package: every layer may use them
    assert not graph["errors"] and not graph["text"], (graph["errors"], graph["text"])
    # A run's storage (files on a shared path or an object store) sits just above the leaves:
    # the learner writes its checkpoints through it.
    assert graph["storage"] <= leaves, graph["storage"]
    assert graph["learner"] <= leaves | {"config", "storage"}, graph["learner"]
    assert graph["protocol"] <= leaves, graph["protocol"]
    # Supervision (restart policy, health checks) sits below the envs: an env that runs its
    # robot in process supervises it with the supervisor's own rules.
    assert graph["supervision"] <= leaves | {"protocol", "robots", "config"}, graph["supervision"]
    assert graph["envs"] <= leaves | {"protocol", "robots", "config", "supervision"}, graph["envs"]
    assert "distributed" not in graph["experience"] | graph["supervision"] | graph["realrobot"]


ROBOT_FAMILIES = frozenset(
    p.name for p in (PACKAGE / "robots").iterdir() if (p / "card.py").is_file()
)
"""The robot folders: ``robots/<family>/`` with a ``card.py``."""


def test_a_robot_folder_is_imported_only_by_itself_and_its_own_tasks() -> None:
    """A robot is its folder: the shared robot side (``robots/*.py``) and every other folder
    reach it through its card (the registry names card modules by string, not by import).
    Only the envs' modules named after the family (``envs/ur_tasks.py``, ``envs/render/ur.py``)
    may import it, and no robot folder imports another."""
    assert {"mir100", "ur"} <= ROBOT_FAMILIES
    offenders = []
    for path in PACKAGE.rglob("*.py"):
        rel = path.relative_to(PACKAGE)
        for name in imports(path):
            parts = name.split(".")
            if parts[:2] != ["robogym_ray", "robots"] or len(parts) < 3:
                continue
            family = parts[2]
            if family not in ROBOT_FAMILIES:
                continue
            own = rel.parts[:2] == ("robots", family)
            tasks = rel.parts[0] == "envs" and rel.stem.startswith(family)
            if not (own or tasks):
                offenders.append(f"{rel} imports {name}")
    assert offenders == []


def loaded_after(code: str, modules: tuple[str, ...]) -> list[str]:
    """Which of ``modules`` a fresh interpreter has imported after running ``code``."""
    probe = code + f"import sys; print(sorted(m for m in {modules!r} if m in sys.modules))\n"
    done = children.run(
        [sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, check=True
    )
    return ast.literal_eval(done.stdout.strip().splitlines()[-1])


def test_a_sim_env_imports_neither_ray_nor_torch() -> None:
    code = (
        "import gymnasium as gym, robogym_ray.envs\n"
        "env = gym.make('RoboGymRay/ObstacleAvoidanceMir100Sim-v0')\n"
        "env.reset(seed=0); env.step(env.action_space.sample()); env.close()\n"
    )
    assert loaded_after(code, ("ray", "torch")) == []


def test_the_robot_side_of_ray_imports_no_torch() -> None:
    """A Ray actor's process imports the module its class is defined in: the supervisor's, each
    robot server's and each real robot's must not pull in torch (a manager starts dozens of
    robot servers), nor must the ``manager`` and ``resume-robot`` commands."""
    code = (
        "import robogym_ray.distributed.robot_actors, robogym_ray.distributed.manager\n"
        "import robogym_ray.distributed.provider, robogym_ray.distributed.resume\n"
    )
    assert loaded_after(code, ("ray", "torch")) == ["ray"]
