"""Every package.xml declares what its package imports (rosdep keys where they exist; the pip-only
ones named in its comment), and no Python library it does not import (ROS packages it needs
without importing them, e.g. the entity kinds it loads by name, may be declared)."""

import ast
import re
import sys
import xml.etree.ElementTree as ElementTree
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PACKAGES = {'itasc_core': ROOT / 'src/itasc_core', 'itasc_tasks': ROOT / 'src/itasc_tasks',
            'itasc_drivers': ROOT / 'src/itasc_drivers', 'itasc_bringup': ROOT / 'bringup'}
#: Python module -> rosdep key (a ROS package's module is its own key).
ROSDEP = {'numpy': 'python3-numpy', 'yaml': 'python3-yaml', 'pydantic': 'python3-pydantic',
          'pinocchio': 'pinocchio', 'scipy': 'python3-scipy', 'transitions': 'python3-transitions',
          'matplotlib': 'python3-matplotlib', 'mpl_toolkits': 'python3-matplotlib', 'graphviz': 'python3-graphviz',
          'rich': 'python3-rich', 'argcomplete': 'python3-argcomplete', 'setproctitle': 'python3-setproctitle'}
#: Modules without a rosdep key: named in the package.xml's "pip only" comment instead.
PIP_ONLY = {'qpsolvers', 'daqp', 'mcap', 'rosbags'}


def imported(package: Path) -> set[str]:
    """Top-level modules the package's Python files import, stdlib and the package itself left out."""
    name = package.name if package.name != 'bringup' else 'itasc_bringup'
    modules = set()
    for path in (package / name).rglob('*.py'):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Import):
                modules |= {alias.name.split('.')[0] for alias in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                modules.add(node.module.split('.')[0])
    return {m for m in modules if m not in sys.stdlib_module_names and m != name}


def declared(package: Path) -> tuple[set[str], set[str]]:
    """(exec_depend/depend keys, modules named in the pip-only comment) of the package.xml."""
    text = (package / 'package.xml').read_text()
    root = ElementTree.fromstring(text)
    keys = {e.text for tag in ('depend', 'exec_depend') for e in root.iter(tag)}
    comment = re.search(r'pip only[^:]*:([^-]*)-->', text)
    pip = {m.strip() for m in comment.group(1).split(',')} if comment else set()
    return keys, pip


@pytest.mark.parametrize('name', sorted(PACKAGES))
def test_package_xml_declares_what_the_package_imports(name):
    package = PACKAGES[name]
    modules = imported(package)
    keys, pip = declared(package)
    needed = {ROSDEP.get(m, m) for m in modules - PIP_ONLY}
    assert sorted(needed - keys) == [], f'{name}/package.xml lacks these exec_depends'
    assert sorted((modules & PIP_ONLY) - pip) == [], f'{name}/package.xml: name these in its pip-only comment'
    libraries = {k for k in keys if k.startswith('python3-') or k in ROSDEP.values()}
    assert sorted(libraries - needed) == [], f'{name}/package.xml declares libraries it does not import'
    assert sorted(pip - modules) == [], f'{name}/package.xml names pip-only modules it does not import'
