"""Attribute docstrings as field descriptions, each module's source read once.

Every model of the project documents its fields with the docstring under each (the description in
the JSON schema, ``docs/model.md`` and a ROS parameter's descriptor). pydantic's
``use_attribute_docstrings`` finds them by walking the stack frames of each class definition and
parsing the class's source again: about 0.2 s of CPU at every process start for the ~70 models
read from files. :class:`Documented`, the metaclass of the project's base models, parses each
module once and hands pydantic the descriptions as if they had been given with ``Field``.
"""

from __future__ import annotations

import ast
import functools
import inspect
import sys
from typing import TYPE_CHECKING, Any

from pydantic import BaseModel, Field
from pydantic.fields import FieldInfo

if TYPE_CHECKING:  # the type checker needs the class by name; at run time it is BaseModel's metaclass
    from pydantic._internal._model_construction import ModelMetaclass
else:
    ModelMetaclass = type(BaseModel)

__all__ = ['Documented']


class Documented(ModelMetaclass):
    """pydantic's model metaclass, with each field's docstring as its description (where it has none)."""

    def __new__(mcs, name: str, bases: tuple[type, ...], namespace: dict[str, Any], *args: Any,
                **kwargs: Any) -> type:
        docs = _class_docstrings(namespace.get('__module__', ''), namespace.get('__qualname__', name))
        annotations = namespace.get('__annotations__', {})
        for field, doc in docs.items():
            if field.startswith('_') or field not in annotations or 'ClassVar' in str(annotations[field]):
                continue
            value = namespace.get(field, ...)
            if isinstance(value, FieldInfo):
                if value.description is None:
                    namespace[field] = FieldInfo.merge_field_infos(value, description=doc)
            elif value is ... or not callable(getattr(value, '__get__', None)):  # not a descriptor
                namespace[field] = Field(value, description=doc)
        return super().__new__(mcs, name, bases, namespace, *args, **kwargs)


def _class_docstrings(module: str, qualname: str) -> dict[str, str]:
    file = getattr(sys.modules.get(module), '__file__', None)
    return _module_docstrings(file).get(qualname, {}) if file else {}


@functools.cache
def _module_docstrings(file: str) -> dict[str, dict[str, str]]:
    """Per class of the module ``file`` (by qualified name): its fields' docstrings, the string
    right under an annotated assignment, as pydantic reads them."""
    try:
        with open(file, encoding='utf-8') as source:
            tree = ast.parse(source.read(), filename=file)
    except (OSError, SyntaxError, ValueError):
        return {}
    found: dict[str, dict[str, str]] = {}

    def visit(body: list[ast.stmt], prefix: str) -> None:
        for node in body:
            if isinstance(node, ast.ClassDef):
                qualname = prefix + node.name
                docs = found.setdefault(qualname, {})
                for first, second in zip(node.body, node.body[1:]):
                    if isinstance(first, ast.AnnAssign) and isinstance(first.target, ast.Name) \
                            and isinstance(second, ast.Expr) and isinstance(second.value, ast.Constant) \
                            and isinstance(second.value.value, str):
                        docs[first.target.id] = inspect.cleandoc(second.value.value)
                visit(node.body, qualname + '.')
    visit(tree.body, '')
    return found
