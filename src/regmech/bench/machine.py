"""The machine and software a benchmark ran on (``lscpu``, ``nproc``, package versions)."""

from __future__ import annotations

import datetime
import os
import platform
import shutil
import subprocess
import sys


def _lscpu_model() -> str:
    if shutil.which("lscpu"):
        try:
            out = subprocess.run(["lscpu"], capture_output=True, text=True, timeout=10).stdout
            for line in out.splitlines():
                if line.startswith("Model name:"):
                    return line.split(":", 1)[1].strip()
        except (OSError, subprocess.SubprocessError):
            pass
    return platform.processor() or platform.machine()


def _version(dist: str) -> str:
    from importlib import metadata
    try:
        return metadata.version(dist)
    except metadata.PackageNotFoundError:
        return "not installed"


def machine_info() -> dict[str, str]:
    import regmech
    cores = os.cpu_count() or 0
    if shutil.which("nproc"):
        try:
            cores = int(subprocess.run(["nproc"], capture_output=True, text=True, timeout=10).stdout.strip())
        except (OSError, ValueError, subprocess.SubprocessError):
            pass
    return {
        "cpu": _lscpu_model(),
        "cores (nproc)": str(cores),
        "os": f"{platform.system()} {platform.release()} ({platform.machine()})",
        "python": sys.version.split()[0],
        "numpy": _version("numpy"),
        "scipy": _version("scipy"),
        "scikit-sundae": _version("scikit-sundae"),
        "regmech": regmech.__version__,
        "date": datetime.datetime.now().strftime("%Y-%m-%d %H:%M"),
    }


def machine_line(info: dict[str, str]) -> str:
    return ", ".join(f"{k} {v}" for k, v in info.items())
