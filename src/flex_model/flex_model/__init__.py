"""flex_model: flexible-link arm models and the simulation core; the ROS 2 adapters (the
model node) are the subpackage :mod:`flex_model.ros`. Importing the package changes no
environment variable and imports no ROS."""

__version__ = "0.1.0"
