"""Configuration (paper §5): the Configurator and its named configurations."""

from .configurator import Configurator

__all__ = ['Configurator']
