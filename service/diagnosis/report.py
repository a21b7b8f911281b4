"""Stage 5 — the report: the JSON-ready result (the contract in docs/diagnosis.md), its plain
text form and the residual plot."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..mechanics.effects import SHAPES
from .data import BLOCK, STATE, model_curve
from .decision import Decision
from .evidence import Evidence
from .hypotheses import Fits
from .phases import phase_bounds
from .whiteness import ljung_box


def _ratio(z) -> float:
    """rmse/noise per sample from whitened block-mean residuals z (noise included)."""
    if z.size == 0:
        return 1.0
    return float(np.sqrt(1.0 + max(float(np.mean(z * z)) - 1.0, 0.0) / BLOCK))


def _params(x, operation, extra=None):
    d = {k: float(v) for k, v in zip(STATE[operation], x)}
    d["onset_delay_s"] = float(x[-1])
    return d


def build(fits: Fits, ev: Evidence, dec: Decision, next_meas: list, holdout, runtime_s: float) -> dict:
    w = fits.windows
    op, br, caps = w.operation, w.breaker, w.captures
    chosen = fits.hypotheses[dec.hypothesis]
    if dec.status != "named":
        chosen = fits.hypotheses["none"]
    after = [cw.project_out(cw.r - s) for cw, s in zip(chosen.captures, chosen.signatures)]
    before = [cw.project_out(cw.r) for cw in caps]

    # where: phases of each capture's fitted reduced curve, pooled over captures
    where = []
    per_phase = {}
    for cw, zb, za in zip(caps, before, after):
        d = cw.data
        theta = model_curve(cw.x, d, br, op)
        tm = d.t - cw.x[-1]
        for name, a, b in phase_bounds(op, tm, theta, float(tm[-1]), br):
            sel = (tm >= a) & (tm <= b)
            acc = per_phase.setdefault(name, {"t0_s": d.t_start + cw.x[-1] + a, "t1_s": d.t_start + cw.x[-1] + b,
                                              "zb": [], "za": []})
            acc["zb"].append(zb[sel])
            acc["za"].append(za[sel])
    for name, acc in per_phase.items():
        where.append({"phase": name, "t0_s": float(acc["t0_s"]), "t1_s": float(acc["t1_s"]),
                      "gap_before": _ratio(np.concatenate(acc["zb"])),
                      "gap_after": _ratio(np.concatenate(acc["za"]))})

    noise = float(np.sqrt(np.mean([cw.data.noise ** 2 for cw in caps])))
    zb, za = np.concatenate(before), np.concatenate(after)
    rb, ra = _ratio(zb), _ratio(za)
    gb, ga = np.sqrt(max(rb * rb - 1, 0)), np.sqrt(max(ra * ra - 1, 0))
    gap = {"before_rms_rad": rb * noise, "after_rms_rad": ra * noise, "noise_rad": noise,
           "shrink": float(1 - ga / gb) if gb > 0 else 0.0,
           "gap_sigma": float(dec.gap_sigma),
           "ljung_box_p_before": float(min(ljung_box(cw.project_out(cw.r))[1] for cw in caps)),
           "ljung_box_p_after": float(min(ljung_box(z)[1] for z in after))}

    reduced = [_params(cw.x, op) for cw in caps]
    corrected = []
    for cw, s in zip(chosen.captures, chosen.signatures):
        corrected.append(_params(cw.x + cw.state_step(cw.r - s), op))
    named = []
    if chosen.effects and dec.status == "named":
        for e, s, sh in chosen.as_effects():
            named.append({"effect": e, "strength": s, "shape": {n[0]: float(v) for n, v in zip(SHAPES[e], sh)},
                          "mild": e in dec.mild})
    probs = dict(sorted(ev.probabilities.items(), key=lambda kv: -kv[1]))
    return {
        "operation": op, "breaker": br.name, "captures": len(caps),
        "sources": [cw.data.source for cw in caps],
        "status": dec.status, "effects": list(dec.effects), "named": named,
        "probabilities": probs, "rivals": dec.rivals, "mild": dec.mild,
        "answer": dec.answer, "answer_probability": float(dec.answer_probability),
        "answers": dict(sorted(dec.answers.items(), key=lambda kv: -kv[1])),
        "absorbed": dec.absorbed, "where": where, "gap": gap,
        "reduced_parameters": reduced, "corrected_parameters": corrected,
        "next_measurement": next_meas,
        "holdout_shrink": holdout,
        "bic": ev.bic, "dispersion": ev.dispersion, "blocks": ev.n,
        "message": message(dec, probs, gap, len(caps)),
        # issue-11 keys kept for the operation page until it moves to the keys above
        "verdict": "+".join(dec.effects) if dec.status == "named" else dec.status,
        "candidates": [{"effect": k, "probability": p} for k, p in list(probs.items())[:6]],
        "how_far": None,
        "runtime_s": float(runtime_s),
    }


def message(dec: Decision, probs, gap, n) -> str:
    ratio = gap["before_rms_rad"] / gap["noise_rad"]
    who = f"{n} capture{'s' if n > 1 else ''}"
    if dec.status == "none":
        if dec.mild:
            return (f"No gap that matters over {who} ({ratio:.2f}× the noise floor); present but mild: "
                    f"{', '.join(dec.mild)}.")
        return f"The reduced model fits {who} to the noise floor ({ratio:.2f}×): no unmodelled effect."
    if dec.status == "named":
        p = dec.answer_probability
        extra = f" ({', '.join(dec.mild)} present but mild)" if dec.mild else ""
        return (f"{' and '.join(dec.effects)}{extra} (probability {p:.2f}) explains the gap over {who}: "
                f"{gap['before_rms_rad'] * 1e3:.2f} → {gap['after_rms_rad'] * 1e3:.2f} mrad rms.")
    if dec.status == "unexplained":
        return (f"A gap of {ratio:.2f}× the noise floor over {who} that no catalogued effect describes "
                f"(outside the catalogue, probability {probs['outside_catalogue']:.2f}).")
    return ("Ambiguous: " + ", ".join(f"{r['effect']} {r['probability']:.2f}" for r in dec.rivals)
            + f" over {who}; see next_measurement.")


def format_report(result: dict) -> str:
    g = result["gap"]
    lines = [f"hvcb diagnose: {result['operation']} on breaker {result['breaker']}, {result['captures']} capture(s)",
             f"status: {result['status']}  {result['message']}",
             f"gap: {g['before_rms_rad'] * 1e3:.3f} -> {g['after_rms_rad'] * 1e3:.3f} mrad rms, noise "
             f"{g['noise_rad'] * 1e3:.3f} mrad, shrink {100 * g['shrink']:.0f} %",
             "where (rms/noise before -> after):"]
    for ph in result["where"]:
        lines.append(f"  {ph['phase']:<18} {ph['t0_s'] * 1e3:7.1f}-{ph['t1_s'] * 1e3:7.1f} ms  "
                     f"{ph['gap_before']:5.3f} -> {ph['gap_after']:5.3f}")
    lines.append("probabilities:")
    for k, p in list(result["probabilities"].items())[:6]:
        lines.append(f"  {k:<40} {p:.3f}")
    for a in result["absorbed"]:
        bias = ", ".join(f"{k} {100 * v:+.1f} %" for k, v in a["parameter_bias"].items())
        lines.append(f"absorbed: {a['effect']} (realistic strength) would bias {bias}")
    for m in result["next_measurement"][:3]:
        lines.append(f"next: {m['measurement']} (expected ΔBIC {m['expected_delta_bic']:.0f}, "
                     f"{' vs '.join(m['separates'])})")
    lines.append(f"runtime {result['runtime_s']:.1f} s")
    return "\n".join(lines)


def plot_residuals(result: dict, before, after, t, path: str | Path) -> Path:
    """PNG of the residual [mrad] vs time, before and after the chosen correction, phases shaded."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(9, 4))
    for i, ph in enumerate(result["where"]):
        ax.axvspan(ph["t0_s"] * 1e3, ph["t1_s"] * 1e3, color=f"C{i}", alpha=0.08)
        ax.text(0.5 * (ph["t0_s"] + ph["t1_s"]) * 1e3, 0, ph["phase"], ha="center", fontsize=7)
    ax.plot(t * 1e3, before * 1e3, lw=0.8, label="reduced model")
    if after is not None:
        ax.plot(t * 1e3, after * 1e3, lw=0.8, label="with " + (" + ".join(result["effects"]) or "nothing"))
    ax.set_xlabel("time [ms]")
    ax.set_ylabel("residual (block mean) [mrad]")
    ax.legend()
    ax.set_title(f"{result['operation']}: {result['status']}")
    fig.tight_layout()
    path = Path(path)
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path
