"""The thesis reproduction harness (outside the wheel)."""
