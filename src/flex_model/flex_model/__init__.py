"""flex_model: flexible-link arm models, simulation core and the model node."""

__version__ = "0.1.0"
