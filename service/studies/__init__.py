"""The paper's studies (Yan et al. 2026, Section 4.2): ``hvcb study NAME --out DIR``.

Each study is one module with ``run(out_dir, *, seed, quick) -> dict`` writing a JSON file, a
Markdown table and PNG figures through :mod:`service.studies.report`.
"""
