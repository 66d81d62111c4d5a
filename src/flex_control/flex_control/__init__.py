"""flex_control: controllers for the flex-twin flexible-link arm models."""
