"""Plain-text report and PNG plots of a diagnosis (plotting kept apart from the analysis)."""

from __future__ import annotations

from pathlib import Path


def format_report(result: dict) -> str:
    g = result["gap"]
    lines = [f"hvcb diagnose: {result['operation']} on breaker {result['breaker']}, "
             f"{len(result['captures'])} capture(s)",
             f"gap: RMSE {g['rmse_rad'] * 1e3:.2f} mrad, noise floor {g['noise_rad'] * 1e3:.2f} mrad "
             f"({g['ratio_to_noise']:.2f}×), Ljung–Box p = {g['ljung_box_p']:.2g}",
             "where (first capture):"]
    for ph in g["phases"]:
        lines.append(f"  {ph['name']:<18} {ph['t0_s'] * 1e3:7.1f}–{ph['t1_s'] * 1e3:7.1f} ms  "
                     f"RMSE {ph['rmse_rad'] * 1e3:6.2f} mrad  {ph['ratio_to_noise']:5.2f}× noise  p={ph['p_value']:.2g}")
    lines.append("which (best first):")
    for c in result["candidates"]:
        lines.append(f"  {c['effect']:<20} RMSE {c['rmse_rad'] * 1e3:6.2f} mrad  shrink {100 * c['shrink']:5.1f} %  "
                     f"ΔBIC {c['delta_bic']:9.1f}  hold-out {100 * c['holdout_shrink']:5.1f} %  "
                     f"{'' if c['distinguishable'] else '(absorbed at this noise)'}")
    lines.append(f"verdict: {result['verdict']}")
    hf = result.get("how_far")
    if hf:
        lines.append(f"how far: {hf['rmse_rad_before'] * 1e3:.2f} -> {hf['rmse_rad_after'] * 1e3:.2f} mrad "
                     f"(shrink {100 * hf['shrink']:.0f} %), strength {hf['strength']:.3g}")
        lines.append("  corrected parameters: " + ", ".join(f"{k}={v:.5g}" for k, v in hf["corrected_parameters"].items()))
    for a in result["absorbed"]:
        shift = ", ".join(f"{k} {v:+.1f} %" for k, v in a["parameter_shift"].items() if k != "onset_delay_us")
        lines.append(f"absorbed: {a['effect']} at strength {a['strength']:g} would shift {shift}")
    for w in result["warnings"]:
        lines.append(f"warning: {w}")
    lines.append(f"runtime {result['runtime_s']:.1f} s")
    return "\n".join(lines)


def plot_residuals(result: dict, before, after, t, path: str | Path) -> Path:
    """PNG of the residual [mrad] vs time, before and after the chosen effect, phases shaded."""
    from service.plots import pyplot

    plt = pyplot("--plot")

    fig, ax = plt.subplots(figsize=(9, 4))
    for i, ph in enumerate(result["gap"]["phases"]):
        ax.axvspan(ph["t0_s"] * 1e3, ph["t1_s"] * 1e3, color=f"C{i}", alpha=0.08)
        ax.text(0.5 * (ph["t0_s"] + ph["t1_s"]) * 1e3, 0, ph["name"], ha="center", fontsize=7)
    ax.plot(t * 1e3, before * 1e3, lw=0.8, label="reduced model")
    if after is not None:
        ax.plot(t * 1e3, after * 1e3, lw=0.8, label=f"with {result['verdict']}")
    ax.set_xlabel("time [ms]")
    ax.set_ylabel("residual (block mean) [mrad]")
    ax.legend()
    ax.set_title(f"{result['operation']}: verdict {result['verdict']}")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
