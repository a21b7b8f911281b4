"""``hvcb study NAME --out DIR [--seed N] [--quick] [--workers N]``: the registry of studies.

Every entry is ``"module:function"`` with the signature
``run(out_dir: Path, *, seed: int = ..., quick: bool = False) -> dict``; a study may also accept
``workers``. Modules are imported only when their study runs, so a study whose module is not
there yet gives a one-line error instead of breaking the whole command.
"""

from __future__ import annotations

import importlib
import inspect
from pathlib import Path

STUDIES = {
    "identifiability": "service.studies.identifiability:run",
    "sensitivity": "service.studies.sensitivity:run",
    "correlation": "service.studies.correlation:run",
    "optimizers": "service.studies.optimizers:run",
    "conditions": "service.studies.conditions:run",
    "classify": "service.studies.classify:run",
    "classify-pairs": "service.studies.classify_pair_run:run",
    "gap": "service.studies.gap:run_gap_study",
}


class StudyUnavailable(ValueError):
    """The named study is unknown or its module is not installed in this tree."""


def load_study(name: str):
    """The ``run`` function of study ``name``; raises :class:`StudyUnavailable`."""
    target = STUDIES.get(name)
    if target is None:
        raise StudyUnavailable(f"unknown study {name!r}; choose one of {', '.join(STUDIES)}")
    module_name, func_name = target.split(":")
    try:
        module = importlib.import_module(module_name)
    except ModuleNotFoundError as exc:
        if exc.name and module_name.startswith(exc.name):
            raise StudyUnavailable(f"study {name!r} is not available in this installation "
                                   f"({module_name} is missing)") from None
        raise
    func = getattr(module, func_name, None)
    if func is None:
        raise StudyUnavailable(f"study {name!r} is not available: {module_name} has no {func_name}()")
    return func


def run_study(name: str, out_dir, *, seed: int | None = None, quick: bool = False,
              workers: int | None = None) -> dict:
    """Run one study into ``out_dir``; options the study does not take are not passed."""
    func = load_study(name)
    accepted = inspect.signature(func).parameters
    kwargs = {"quick": quick}
    if seed is not None:
        kwargs["seed"] = seed
    if workers is not None and "workers" in accepted:
        kwargs["workers"] = workers
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    return func(out, **kwargs)


def register(subparsers) -> None:
    p = subparsers.add_parser("study", help="reproduce one of the paper's studies",
                              description="Run a study and write its JSON, Markdown table and "
                                          "PNG figures into --out.")
    p.add_argument("name", choices=sorted(STUDIES), metavar="NAME",
                   help="one of: " + ", ".join(STUDIES))
    p.add_argument("--out", required=True, type=Path, help="output directory")
    p.add_argument("--seed", type=int, default=None, help="master seed (each study has a default)")
    p.add_argument("--quick", action="store_true", help="reduced size, for tests")
    p.add_argument("--workers", type=int, default=None,
                   help="worker processes for studies that fit many captures (default 2)")
    p.set_defaults(func=_cmd_study)


def _cmd_study(args) -> int:
    if args.workers is not None and args.workers < 1:
        raise ValueError("--workers must be at least 1")
    from service.plots import require_matplotlib

    require_matplotlib("study figures")  # every study writes PNGs; say so before hours of work
    summary = run_study(args.name, args.out, seed=args.seed, quick=args.quick, workers=args.workers)
    verdict = summary.get("acceptance", {}) if isinstance(summary, dict) else {}
    print(f"study {args.name}: results in {args.out}")
    for key, ok in verdict.items():
        if isinstance(ok, bool):
            print(f"  {key}: {'pass' if ok else 'FAIL'}")
    return 0
