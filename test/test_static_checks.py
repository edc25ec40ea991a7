"""Static checks of the whole repository, configured in pyproject.toml: ruff (lint) and mypy (types).
A finding fails the suite; a rule that does not fit is switched off there, with its reason."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def _run(*command: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, '-m', *command], cwd=ROOT, capture_output=True, text=True, timeout=240)


def test_ruff_finds_nothing():
    result = _run('ruff', 'check', '--no-cache', '--output-format', 'concise', '.')
    assert result.returncode == 0, result.stdout + result.stderr


def test_mypy_finds_nothing():
    result = _run('mypy', '--no-incremental', '--cache-dir', '/dev/null')
    assert result.returncode == 0, result.stdout + result.stderr
