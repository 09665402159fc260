"""Reading TOML configuration files (vehicles, gains, tuning specs) with one error format."""

from __future__ import annotations

import tomllib
from pathlib import Path

from rotorlab.errors import ConfigError


def read_toml(path, kind: str) -> dict:
    """Parse the TOML file ``path``; ``kind`` ("vehicle", "gains", "spec") names it in the errors."""
    path = Path(path)
    try:
        with open(path, "rb") as fh:
            return tomllib.load(fh)
    except FileNotFoundError:
        raise ConfigError(f"{kind} file not found", file=path) from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"not valid TOML: {exc}", file=path) from None
