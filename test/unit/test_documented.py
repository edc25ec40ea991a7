"""Field docstrings become descriptions (:mod:`itasc_core.documented`), as pydantic's
``use_attribute_docstrings`` made them, without its walk over the stack at every class."""

from __future__ import annotations

from typing import ClassVar

from pydantic import BaseModel, Field

from itasc_core.documented import Documented


class Gains(BaseModel, metaclass=Documented):
    kp: float = 1.0
    """Proportional gain."""
    ki: float = Field(default=0.0, ge=0)
    """Integral gain."""
    kd: float = Field(default=0.0, description='said with Field')
    """Not this one: a description given with Field stands."""
    required: int
    """A field without a default stays required."""
    undocumented: float = 2.0
    scale: ClassVar[float] = 3.0
    """A class variable is no field."""

    class Limits(BaseModel, metaclass=Documented):
        upper: float = 1.0
        """Of a nested class too."""


def test_a_fields_docstring_is_its_description_and_what_it_was_given_stands():
    fields = Gains.model_fields
    assert fields['kp'].description == 'Proportional gain.' and fields['kp'].default == 1.0
    assert fields['ki'].description == 'Integral gain.' and fields['ki'].metadata[0].ge == 0
    assert fields['kd'].description == 'said with Field'
    assert fields['required'].is_required() and fields['required'].description.startswith('A field without')
    assert fields['undocumented'].description is None
    assert 'scale' not in fields and Gains.scale == 3.0
    assert Gains.Limits.model_fields['upper'].description == 'Of a nested class too.'
    assert Gains(required=1).kp == 1.0


def test_the_project_models_keep_their_descriptions():
    from itasc_bringup.model.schema import Application
    from itasc_tasks.controllers.pid import PIDController
    assert PIDController.Parameters.model_fields['ki'].description == 'Integral gain [1/s²] (finite).'
    assert Application.model_fields['rate'].description == 'The control rate [Hz].'
    assert Application.model_fields['hosts'].description.startswith('Composites on other machines')
