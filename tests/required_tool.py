"""Tests that need a tool outside the build (Blender, say): on a developer's machine a
missing tool skips the test, but under CI (the variable CI set, as .ci/run's hosts and most
CI services set it) every tool is installed on purpose, and a skip there would pass a check
that never ran. The Python side of tests/support/cpp/required_tool.h."""
import os

import pytest


def running_under_ci():
    return bool(os.environ.get("CI"))


def require_tool(available, message):
    """Skips the calling test when `available` is false, or fails it under CI."""
    if available:
        return
    if running_under_ci():
        pytest.fail(f"{message} (CI is set, so a missing tool is a failure)")
    pytest.skip(message)
