"""The ``hvcb`` command. Each domain package registers its own subcommands; errors reach the
user as one line and a non-zero exit, never a traceback."""

from __future__ import annotations

import argparse
import importlib
import sys

# Each module defines ``register(subparsers)``; subcommands set ``func(args) -> int``.
COMMAND_MODULES = (
    "service.estimation.commands",
    "service.studies.commands",
    "service.acquisition.commands",
    "service.api.commands",
    "service.diagnosis.commands",
    "drivers.commands",
)


class UserError(Exception):
    """An error whose message is meant for the person at the terminal."""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="hvcb", description="HV circuit-breaker mechanism monitor")
    sub = parser.add_subparsers(dest="command", required=True)
    for name in COMMAND_MODULES:
        try:
            module = importlib.import_module(name)
        except ModuleNotFoundError as exc:
            if exc.name and name.startswith(exc.name):
                continue  # that domain has no commands yet
            raise
        module.register(sub)
    return parser


def main(argv=None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        return 130
    except (UserError, ValueError, OSError) as exc:
        print(f"hvcb {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
