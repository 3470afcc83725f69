"""A lab's driver module that fails as it loads (tests/drivers/test_registry.py)."""

raise RuntimeError("the lab's module is broken")
