"""The line that says which machine a benchmark ran on."""

import os
import platform


def machine_line() -> str:
    return f"{platform.machine()}, {os.cpu_count()} cores, Python {platform.python_version()}"
