"""The validation bank's halves that live outside the packages (not installed by pyproject)."""
