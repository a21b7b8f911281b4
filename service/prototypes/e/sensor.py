"""Prototype E: the travel transducer, its conversion, the vibration and the noise.

Travel chain: a linear (potentiometric) transducer of 150 mm stroke is driven by a slotted
lever of radius r_L on the output shaft (sliding block in the slot, transducer axis fixed):

    p = p_off + r_L (sin(beta + tau) - sin(beta))            [m, true position]
    p_nl = p + s_nl * INL * FS * shape(p / FS)              (sensor_nonlinearity)
    p_read = p_off + g (p_nl - p_off) + z + n + quantisation (gain g, zero z, noise n)
    tau_rec = asin((p_read - p_off)/R_nom + sin(beta_nom)) - beta_nom   [rad]

The recording is converted with the *nominal* lever (R_nom = 100 mm, beta_nom = -0.5 rad),
as a utility configures it; the unit's lever radius (+-0.3 mm) and mounting angle
(+-0.5 deg), the gain (+-1 %) and the zero (+-2 mrad equivalent) stay in the data.

Vibration: the output shaft's torsional modes (f1 550-750 Hz, f2 1400-1900 Hz per unit)
are struck by the torque steps of the latch release and of impacts (buffer engagement,
end of the closing); their amplitude is participation x torque step / torsional stiffness
of the shaft between the spring crank and the sensor lever (steel shaft 60 mm, 0.3 m:
GJ/L = 3.4e5 N m/rad).  During motion the linkage's pin clearances rattle: white noise
through the first mode's resonance (coloured), rms proportional to the speed.
"""
from __future__ import annotations

import math

import numpy as np
from scipy.signal import lfilter

from . import model as M

K_TORSION = 3.4e5          # N m / rad
PARTICIPATION = (0.25, 0.10)
RATTLE_RMS = 1.5e-4        # rad at the peak speed of the stroke
FS = M.TRANSDUCER_FS
LSB = FS / 2 ** M.ADC_BITS


def _shape_raw(x):
    return np.sin(np.pi * x) + 0.3 * np.sin(3.0 * np.pi * x)


_SHAPE_NORM = float(np.max(np.abs(_shape_raw(np.linspace(0.0, 1.0, 10001)))))


def inl_shape(x):
    """Integral nonlinearity shape of the transducer (bow + third-order ripple), max 1."""
    return _shape_raw(x) / _SHAPE_NORM


def position(tau, u: M.Unit, s_nl: float = 0.0):
    """Transducer position [m] seen by the unit's lever (with nonlinearity s_nl)."""
    p = M.TRANSDUCER_OFFSET + u.lever_r * (np.sin(u.lever_beta + tau) - math.sin(u.lever_beta))
    if s_nl:
        p = p + s_nl * M.SCALE["sensor_inl"] * FS * inl_shape(p / FS)
    return p


def electrical(p, u: M.Unit):
    return M.TRANSDUCER_OFFSET + u.gain * (p - M.TRANSDUCER_OFFSET) + u.zero_m


def convert(p_read):
    """Nominal conversion transducer position [m] -> output-shaft angle [rad]."""
    arg = (p_read - M.TRANSDUCER_OFFSET) / M.LEVER_R + math.sin(M.LEVER_BETA)
    return np.arcsin(np.clip(arg, -1.0, 1.0)) - M.LEVER_BETA


def reading(tau, u: M.Unit, s_nl: float = 0.0):
    """Noiseless recorded travel [rad] of a true shaft angle tau."""
    return convert(electrical(position(tau, u, s_nl), u))


def noisy_reading(tau_with_vibration, u: M.Unit, s_nl: float, rng: np.random.Generator):
    p = electrical(position(tau_with_vibration, u, s_nl), u)
    p = p + rng.normal(0.0, u.noise_sd_m, p.shape)
    p = np.round(p / LSB) * LSB  # 16-bit ADC over the transducer's stroke
    return convert(p)


def _accel(tau, fs):
    a = np.zeros_like(tau)
    a[1:-1] = (tau[2:] - 2 * tau[1:-1] + tau[:-2]) * fs * fs
    k = np.ones(9) / 9.0
    return np.convolve(a, k, mode="same")


def torque_step(tau, i, J2, fs, half=26):
    a = _accel(tau, fs)
    lo = max(i - half, 0)
    hi = min(i + half, len(tau) - 1)
    return J2 * (a[hi] - a[lo])


def events(op: str, tau, u: M.Unit, fs: float, t0: float, x_contact=None):
    """Indices of the events that strike the structure: latch release, buffer
    engagement (open), the contact touch and the end of the closing (close)."""
    ev = [("latch", int(math.ceil(t0 * fs)))]
    if op == "open":
        idx = np.nonzero(tau > u.alpha0)[0]
        if idx.size:
            ev.append(("buffer", int(idx[0])))
        im = int(np.argmax(tau))
        ev.append(("travel_max", im))
    else:
        if x_contact is not None:
            idx = np.nonzero(x_contact < M.SCALE["main_touch"])[0]
            if idx.size:
                ev.append(("contact_touch", int(idx[0])))
        idx = np.nonzero(tau <= np.min(tau) + 1e-6)[0]
        if idx.size:
            ev.append(("closed", int(idx[0])))
    return ev


def _struck(n, i, amp, f, zeta, fs, phase):
    out = np.zeros(n)
    if i >= n or amp == 0.0:
        return out
    t = np.arange(n - i) / fs
    w = 2 * math.pi * f
    wd = w * math.sqrt(1 - zeta * zeta)
    out[i:] = amp * np.exp(-zeta * w * t) * (np.cos(wd * t + phase) - math.cos(phase) * np.exp(-t * 4000.0))
    return out


def torsional_vibration(op, tau, u: M.Unit, J2, fs, t0, rng, x_contact=None):
    """Shaft torsional vibration seen at the sensor lever [rad] and its description."""
    n = len(tau)
    v = np.zeros(n)
    desc = []
    for name, i in events(op, tau, u, fs, t0, x_contact):
        if name == "travel_max":
            continue
        if name == "latch" and op == "close":
            # the output shaft rests on the cam dwell: the closing latch's release reaches
            # it through the frame; 30 % of the closing spring's torque at release
            th = u.theta1_start
            xc = u.xC0 - u.rC * (1.0 - math.cos(th))
            dT = -0.3 * u.kC * xc * u.rC * u.d * math.sin(th) / (u.d + u.rC * math.cos(th))
        else:
            dT = torque_step(tau, i, J2, fs)
        for k, (f, z, part) in enumerate(zip(u.modes_hz, u.modes_zeta, PARTICIPATION)):
            amp = part * dT / K_TORSION * float(np.exp(rng.normal(0.0, 0.3)))
            ph = float(rng.uniform(-0.5, 0.5))
            v -= _struck(n, i, amp, f, z, fs, ph)
            desc.append(dict(event=name, t_s=i / fs, mode_hz=f, zeta=z, amplitude_rad=amp))
    # linkage rattle: white noise through the first mode's resonance, scaled by speed
    w = np.gradient(tau) * fs
    wmax = max(np.max(np.abs(w)), 1e-9)
    f1, z1 = u.modes_hz[0], u.modes_zeta[0]
    r = math.exp(-z1 * 2 * math.pi * f1 / fs)
    th = 2 * math.pi * f1 * math.sqrt(1 - z1 * z1) / fs
    e = rng.normal(0.0, 1.0, n)
    c = lfilter([1.0], [1.0, -2 * r * math.cos(th), r * r], e)
    c /= max(np.std(c), 1e-12)
    v += RATTLE_RMS * c * np.abs(w) / wmax
    return v, dict(struck=desc, rattle_rms_rad_at_peak_speed=RATTLE_RMS,
                   rattle_mode_hz=f1)


def accelerometer(op, tau, u: M.Unit, J2, fs, t0, rng, x_contact=None):
    """Frame acceleration [g]: frame modes (2.5-6 kHz) struck at the latch release (0.4 ms
    before motion, as the trip latch lets go) and the impacts, plus in-motion broadband
    content and 0.5 g white noise."""
    n = len(tau)
    g = rng.normal(0.0, 0.5, n)
    fr = rng.uniform(2500.0, 6000.0, 3)
    for name, i in events(op, tau, u, fs, t0, x_contact):
        if name == "latch":
            i = max(i - int(round(0.4e-3 * fs)), 0)
            amp = 150.0
        else:
            amp = min(abs(torque_step(tau, i, J2, fs)) * 0.3, 800.0)
        amp *= float(np.exp(rng.normal(0.0, 0.3)))
        for f in fr:
            g += _struck(n, i, amp / 3.0, f, 0.05, fs, float(rng.uniform(0, 2 * math.pi)))
    w = np.abs(np.gradient(tau) * fs)
    g += rng.normal(0.0, 1.0, n) * 8.0 * w / max(w.max(), 1e-9)
    return np.clip(g, -999.0, 999.0)
