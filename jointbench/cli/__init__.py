"""The top floor: the command line ``jointbench`` (:mod:`.command`), one module per group of subcommands
(:mod:`.studies`, :mod:`.history`, :mod:`.estimate`). It parses arguments and calls the Python API
(:mod:`jointbench.api`) or the harness; nothing below imports it (tests/test_architecture.py)."""
from jointbench.cli.command import main

__all__ = ["main"]
