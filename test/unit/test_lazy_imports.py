"""What a process that hosts only Tasks imports (``--deploy per-composite``): the Task entities and
the composite host, but not the Solvers' qpsolvers and scipy.sparse (itasc_core.lazy); one that
runs a Solver only its kind (the registry loads a kind when it is named); ``bootstrap --help`` not
the model schema; the
re-exported names still resolve, and an unknown one is an AttributeError."""

from __future__ import annotations

import subprocess
import sys

import pytest


def _imported(code: str) -> str:
    return subprocess.run([sys.executable, '-c', code], capture_output=True, text=True, check=True).stdout


def test_a_process_hosting_only_tasks_does_not_load_the_solvers():
    out = _imported('import sys\n'
                    'import itasc_core.composition.host, itasc_tasks.entities, itasc_drivers.ports\n'
                    'solvers = ("qpsolvers", "scipy.sparse", "itasc_core.itasc.solver")\n'
                    'print(sorted(m for m in solvers if m in sys.modules))')
    assert out.strip() == '[]'


def test_a_process_running_the_wdls_solver_loads_only_that_kind():
    out = _imported('import sys\n'
                    'from itasc_core.itasc.entities.solver_entity import SolverEntity\n'
                    'SolverEntity.parameters_of({"kind": "wdls", "damping": 0.2})\n'
                    'print(sorted(m for m in ("qpsolvers", "itasc_core.itasc.solver.qp") if m in sys.modules))')
    assert out.strip() == '[]'


def test_the_bootstrap_lists_the_applications_without_building_the_model_schema():
    out = _imported('import contextlib, io, sys\n'
                    'from itasc_bringup.bootstrap import parse_args\n'
                    'text = io.StringIO()\n'
                    'with contextlib.redirect_stdout(text), contextlib.suppress(SystemExit):\n'
                    '    parse_args(["--help"])\n'
                    'print("approach_object" in text.getvalue(), "itasc_bringup.model.schema" in sys.modules)')
    assert out.split() == ['True', 'False']  # --help names the shipped applications, in 0.15 s instead of 3 s


def test_the_re_exported_names_resolve_on_first_use():
    from itasc_core.itasc import QpSolver, Scene, se3
    from itasc_core.itasc.entities import SolverEntity
    from itasc_core.itasc.solver.qp import QpSolver as Defined
    assert QpSolver is Defined and callable(se3) and Scene.__name__ == 'Scene'
    assert SolverEntity.__module__ == 'itasc_core.itasc.entities.solver_entity'
    import itasc_core.itasc
    with pytest.raises(AttributeError, match='no attribute'):
        itasc_core.itasc.NoSuchName  # noqa: B018
