"""flex_planner: trajectory planning for the flex-twin flexible-link arm models."""
