"""The ``hvcb`` command. Each domain package registers its own subcommands; only the module of
the command being run is imported. Errors reach the user as one line and a non-zero exit, never a
traceback."""

from __future__ import annotations

import argparse
import importlib
import sys

from service.errors import UserError

# Subcommand -> module defining ``register(subparsers)``; subcommands set ``func(args) -> int``.
COMMANDS = {
    "fit": ("service.estimation.commands", "fit the dynamic model to one captured operation"),
    "study": ("service.studies.commands", "reproduce a study (identifiability, sensitivity, ...)"),
    "detect": ("service.acquisition.commands", "find operations in a recorded stream"),
    "inspect": ("service.acquisition.inspection", "report what a capture file holds (COMTRADE or CSV)"),
    "capture": ("service.acquisition.commands", "capture operations from a DAQ driver to COMTRADE"),
    "emulate": ("drivers.commands", "run a serial or Modbus DAQ emulator"),
    "serve": ("service.api.commands", "run the monitoring service"),
    "demo": ("service.api.commands", "run the embedded demo (emulated DAQ, SQLite)"),
    "migrate": ("service.api.commands", "apply (or roll back) the database migrations"),
    "key": ("service.api.commands", "create or revoke API keys"),
    "worker": ("service.api.commands", "run a Celery fit worker (scaled-out shape)"),
    "diagnose": ("service.diagnosis.commands", "sim-to-real gap diagnosis of captures"),
    "prune": ("service.storage.commands", "remove raw captures the retention policy no longer keeps"),
    "backup": ("service.storage.commands", "consistent online backup of the database and capture files"),
    "restore": ("service.storage.commands", "restore a backup made by hvcb backup"),
    "commission": ("service.storage.commands", "record a breaker's commissioning close–open pair"),
    "agent": ("service.agent.commands", "edge agent: acquisition only, forwarding captures to a central hvcb"),
    "refit": ("service.refit.commands", "re-fit stored operations (resumable; old results kept)"),
    "report": ("service.reports.commands", "a breaker's condition report (PDF)"),
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="hvcb", description="HV circuit-breaker mechanism monitor")
    sub = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")
    if command in COMMANDS:
        importlib.import_module(COMMANDS[command][0]).register(sub)
    else:
        for name, (_, text) in COMMANDS.items():
            sub.add_parser(name, help=text)
    return parser


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else list(argv)
    command = next((a for a in argv if not a.startswith("-")), None)
    parser = build_parser(command)
    args = parser.parse_args(argv)
    if not hasattr(args, "func"):
        parser.error(f"'{args.command}' is not available in this installation")
    try:
        return int(args.func(args) or 0)
    except KeyboardInterrupt:
        return 130
    except (UserError, ValueError, OSError) as exc:
        print(f"hvcb {args.command}: error: {exc}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
