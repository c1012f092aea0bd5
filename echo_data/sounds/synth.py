"""Procedural synthesis of the 113 built-in sound instances (one seamless loop period each).

An instance id ("phone-train-03") fixes everything: its index in the category selects a style
(so a category always mixes e.g. ringtone timbres, beep patterns, chimes and buzzers), and a
generator seeded with zlib.crc32 of the id draws the rest (melody, pitch, tempo, pattern, flow).
A fresh training instance ("phone-fresh-3fa2b1c94d07", `fresh_id`) is one more draw from the same
generator, outside the 113: its variant index is its number modulo VARIANT_CYCLE, so fresh draws
cover every style of the category, and the id regenerates it anywhere.
`design()` draws the structure (cheap; gives the loop duration without rendering), `render()`
turns it into samples at any rate. All event randomness comes from the id, so the same instance
has the same melody and rhythm at 16 kHz and at 48 kHz.
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from typing import Any

import numpy as np

from echo_data.sounds.dsp import (
    Loop,
    circular_noise,
    cumulative_phase,
    decay_envelope,
    harmonic_tone,
    midi_to_hz,
    partials,
    peak_normalise,
    ramp_envelope,
    seconds_to_samples,
    shaped_burst,
    smooth_periodic,
)

# The instance ids have their own module; synth's users import them from here too.
from echo_data.sounds.instance_ids import VARIANT_CYCLE, builtin_ids, fresh_id, is_fresh_id, parse_builtin_id

# Peak level of one rendered loop per category (dBFS): alarms are shrill and loud, running
# water is a broadband hiss whose peak-normalised level would otherwise dwarf the others.
PEAK_DBFS: dict[str, float] = {"alarm": -1.0, "phone": -3.0, "doorbell": -3.0, "furby": -4.0, "sink": -6.0}

Design = dict[str, Any]
DURATION_GRID_S = 0.04
__all__ = ["PEAK_DBFS", "VARIANT_CYCLE", "builtin_ids", "design", "fresh_id", "is_fresh_id", "parse_builtin_id", "render"]




def _rng(instance_id: str, salt: str) -> np.random.Generator:
    return np.random.default_rng(zlib.crc32(f"{instance_id}:{salt}".encode()))


def design(instance_id: str) -> Design:
    """The instance's structure (style, notes, timing, pitches) with its loop `duration` in seconds."""
    cat, _, k = parse_builtin_id(instance_id)
    d = _DESIGNERS[cat](k, _rng(instance_id, "design"))
    # Round the period up (a slightly longer pause) to the 40 ms grid: an exact whole number of
    # samples at every common rate (8, 11.025, 16, 22.05, 44.1, 48 kHz ...).
    d["duration"] = round(float(np.ceil(float(d["duration"]) / DURATION_GRID_S - 1e-9)) * DURATION_GRID_S, 2)
    return d


def render(instance_id: str, sr: int) -> np.ndarray:
    """One loop period at `sr` (float32, peak at the category's PEAK_DBFS), exactly periodic."""
    cat, _, _ = parse_builtin_id(instance_id)
    d = design(instance_id)
    loop = Loop(seconds_to_samples(d["duration"], sr))
    _RENDERERS[cat](d, loop, sr, _rng(instance_id, "render"))
    return peak_normalise(loop.buf, PEAK_DBFS[cat]).astype(np.float32)


# --------------------------------------------------------------------------- phone
PHONE_STYLES = ("fm_bell", "square", "marimba", "pluck", "classic")
SCALES = ((0, 2, 4, 7, 9), (0, 3, 5, 7, 10), (0, 2, 4, 5, 7, 9, 11), (0, 2, 3, 5, 7, 8, 10), (0, 2, 4, 6, 7, 9, 11))


def _design_phone(k: int, rng: np.random.Generator) -> Design:
    style = PHONE_STYLES[k % len(PHONE_STYLES)]
    if style == "classic":
        return _design_phone_classic(("trill", "double", "bell")[(k // len(PHONE_STYLES)) % 3], rng)
    scale = SCALES[int(rng.integers(len(SCALES)))]
    root = int(rng.integers(57, 69)) if style == "marimba" else int(rng.integers(64, 79))
    unit = float(rng.uniform(0.10, 0.21))
    deg = int(rng.integers(0, len(scale)))
    notes = []
    t = 0.0
    for _ in range(int(rng.integers(5, 10))):
        midi = root + 12 * (deg // len(scale)) + scale[deg % len(scale)]
        units = int(rng.choice([1, 1, 1, 2]))
        notes.append((t, units * unit, midi))
        t += units * unit
        deg = int(np.clip(deg + rng.choice([-3, -2, -1, 1, 1, 2, 3, 0]), -2, len(scale) + 2))  # ~1.5 octaves
    melody = t
    repeats = 2 if melody < 1.5 else 1
    notes = [(t0 + r * melody, g, m) for r in range(repeats) for (t0, g, m) in notes]
    pause = float(rng.uniform(0.3, 0.8))
    timbre = {
        "fm_bell": {"ratio": float(rng.choice([1.4, 2.0, 3.5, 2.76])), "index": float(rng.uniform(1.5, 4.0)), "tau": float(rng.uniform(0.2, 0.6))},
        "square": {"duty": float(rng.choice([0.5, 0.25, 0.125])), "staccato": float(rng.uniform(0.55, 0.9)), "tau": float(rng.uniform(0.4, 2.0))},
        "marimba": {"tau": float(rng.uniform(0.25, 0.55)), "bright": float(rng.uniform(0.2, 0.5))},
        "pluck": {"tau": float(rng.uniform(0.25, 0.7)), "damp": float(rng.uniform(0.6, 1.5))},
    }[style]
    return {"style": style, "notes": notes, "timbre": timbre, "duration": min(4.0, repeats * melody + pause)}


def _design_phone_classic(sub: str, rng: np.random.Generator) -> Design:
    if sub == "trill":
        f1 = float(rng.uniform(600, 1000))
        on = float(rng.uniform(0.9, 1.5))
        bursts = [(0.0, on)]
        if rng.random() < 0.5:
            bursts = [(0.0, on / 2), (on / 2 + 0.25, on / 2)]
        end = bursts[-1][0] + bursts[-1][1]
        return {"style": "trill", "f1": f1, "f2": f1 * float(rng.uniform(1.18, 1.4)), "rate": float(rng.uniform(12, 22)),
                "bursts": bursts, "duration": end + float(rng.uniform(1.0, 2.0))}
    if sub == "double":
        fa = float(rng.uniform(380, 500))
        on = float(rng.uniform(0.3, 0.45))
        gap = float(rng.uniform(0.15, 0.3))
        return {"style": "double", "fa": fa, "fb": fa + float(rng.uniform(25, 70)), "bursts": [(0.0, on), (on + gap, on)],
                "duration": 2 * on + gap + float(rng.uniform(1.4, 2.2))}
    fb = float(rng.uniform(650, 1050))  # a desk telephone's gongs are larger (lower) than an alarm clock's
    on = float(rng.uniform(1.0, 1.8))
    return {"style": "bell", "f1": fb, "f2": fb * float(rng.uniform(1.06, 1.25)), "rate": float(rng.uniform(18, 25)),
            "on": on, "duration": on + float(rng.uniform(1.2, 2.0))}


def _phone_note(style: str, tb: dict[str, float], f: float, gate: float, sr: int) -> np.ndarray:
    """One ringtone note; struck timbres ring past the gate, the square lead stops at it."""
    if style == "square":
        n = seconds_to_samples(gate * tb["staccato"], sr)
        duty = tb["duty"]
        amps = [2.0 / (k * np.pi) * np.sin(k * np.pi * duty) for k in range(1, 60)]
        t = np.arange(n) / sr
        return harmonic_tone(f, n, sr, amps) * ramp_envelope(n, sr, 0.004, 0.012) * np.exp(-t / tb["tau"])
    tau = tb["tau"]
    n = seconds_to_samples(gate + 4 * tau, sr)
    t = np.arange(n) / sr
    if style == "fm_bell":
        mod = tb["ratio"] * f
        index = min(tb["index"], max(0.3, (0.45 * sr - f) / mod - 2))
        y = np.sin(2 * np.pi * f * t + index * np.exp(-t / (0.6 * tau)) * np.sin(2 * np.pi * mod * t))
        return y * decay_envelope(n, sr, tau)
    if style == "marimba":
        b = tb["bright"]
        return partials([f, 4.0 * f, 9.8 * f], [1.0, b, 0.3 * b], [tau, tau / 5, tau / 12], n, sr)
    # pluck: a bright, harmonic attack whose upper partials die faster (kalimba / synth pluck)
    y = np.zeros(n)
    for k in range(1, 11):
        if k * f >= 0.45 * sr:
            break
        y += k**-1.5 * np.exp(-t * (1.0 / tau + tb["damp"] * k * 4)) * np.sin(2 * np.pi * k * f * t)
    return y * decay_envelope(n, sr, 10.0)


def _render_phone(d: Design, loop: Loop, sr: int, rng: np.random.Generator) -> None:
    style = d["style"]
    if style in ("fm_bell", "square", "marimba", "pluck"):
        for t0, gate, midi in d["notes"]:
            loop.add(seconds_to_samples(t0, sr), _phone_note(style, d["timbre"], midi_to_hz(midi), gate, sr))
        return
    if style == "trill":
        for t0, dur in d["bursts"]:
            n = seconds_to_samples(dur, sr)
            t = np.arange(n) / sr
            f = np.where(np.sin(2 * np.pi * d["rate"] * t) >= 0, d["f1"], d["f2"])
            y = harmonic_tone(f, n, sr, [1.0, 0.0, 0.3, 0.0, 0.15])
            loop.add(seconds_to_samples(t0, sr), y * ramp_envelope(n, sr, 0.01, 0.02))
        return
    if style == "double":
        for t0, dur in d["bursts"]:
            n = seconds_to_samples(dur, sr)
            y = harmonic_tone(d["fa"], n, sr, [1.0, 0.15, 0.1]) + harmonic_tone(d["fb"], n, sr, [1.0, 0.15, 0.1])
            loop.add(seconds_to_samples(t0, sr), y * ramp_envelope(n, sr, 0.015, 0.03))
        return
    # electromechanical bell: a hammer alternates between two bells at `rate` strikes per second
    ratios = (1.0, 2.4, 3.9, 5.5)
    n_strikes = int(d["on"] * d["rate"])
    for s in range(n_strikes):
        f = d["f1"] if s % 2 == 0 else d["f2"]
        n = seconds_to_samples(0.35, sr)
        y = partials([r * f for r in ratios], [1.0, 0.5, 0.3, 0.15], [0.12, 0.07, 0.05, 0.03], n, sr,
                     phases=rng.uniform(0, 2 * np.pi, len(ratios)))
        loop.add(seconds_to_samples(s / d["rate"], sr), y * float(rng.uniform(0.75, 1.0)))


# --------------------------------------------------------------------------- alarm
ALARM_STYLES = ("digital", "digital", "bell", "warble")
PIEZO = [1.0, 0.0, 0.35, 0.0, 0.15, 0.0, 0.08]


def _design_alarm(k: int, rng: np.random.Generator) -> Design:
    style = ALARM_STYLES[k % len(ALARM_STYLES)]
    if style == "digital":
        # A unique (pitch band, beeps per group) per digital instance; the rest is drawn.
        lo = 2900.0 if k % len(ALARM_STYLES) == 0 else 1900.0
        f = float(rng.uniform(lo, lo + 1000.0))
        beep = float(rng.uniform(0.05, 0.14))
        gap = float(rng.uniform(0.04, 0.10))
        group = 1 + (k // len(ALARM_STYLES)) % 4
        pause = float(rng.uniform(0.25, 0.7))
        period = group * (beep + gap) + pause
        repeats = int(max(1, min(np.ceil(1.0 / period), 4.0 // period)))
        beeps = [r * period + b * (beep + gap) for r in range(repeats) for b in range(group)]
        return {"style": style, "f": f, "beep": beep, "beeps": beeps, "duration": repeats * period}
    if style == "bell":
        f0 = float(rng.uniform(1800, 3000))
        on = float(rng.uniform(1.2, 2.2))
        return {"style": style, "ratios": [1.0] + sorted((np.array([2.32, 4.25, 6.63]) * rng.uniform(0.95, 1.05, 3)).tolist()),
                "f0": f0, "rate": float(rng.uniform(22, 34)), "tau": float(rng.uniform(0.08, 0.25)), "on": on,
                "duration": on + float(rng.uniform(0.4, 1.0))}
    on = float(rng.uniform(1.0, 2.0))
    sub = "twotone" if (k // len(ALARM_STYLES)) % 2 == 0 else "sweep"
    if sub == "twotone":
        f1 = float(rng.uniform(1800, 3000))
        return {"style": "twotone", "f1": f1, "f2": f1 * float(rng.uniform(1.2, 1.6)), "rate": float(rng.uniform(3, 9)),
                "on": on, "duration": on + float(rng.uniform(0.3, 0.8))}
    return {"style": "sweep", "f1": float(rng.uniform(1000, 2000)), "f2": float(rng.uniform(2500, 3800)),
            "period": float(rng.uniform(0.15, 0.5)), "on": on, "duration": on + float(rng.uniform(0.3, 0.8))}


def _render_alarm(d: Design, loop: Loop, sr: int, rng: np.random.Generator) -> None:
    style = d["style"]
    if style == "digital":
        n = seconds_to_samples(d["beep"], sr)
        y = harmonic_tone(d["f"], n, sr, PIEZO) * ramp_envelope(n, sr, 0.003, 0.004)
        for t0 in d["beeps"]:
            loop.add(seconds_to_samples(t0, sr), y)
        return
    if style == "bell":
        freqs = [r * d["f0"] for r in d["ratios"]]
        taus = [d["tau"] * s for s in (1.0, 0.6, 0.4, 0.3)]
        n = seconds_to_samples(5 * d["tau"], sr)
        click_n = seconds_to_samples(0.003, sr)
        for s in range(int(d["on"] * d["rate"])):
            y = partials(freqs, [1.0, 0.6, 0.4, 0.25], taus, n, sr, phases=rng.uniform(0, 2 * np.pi, len(freqs)))
            y[:click_n] += 0.3 * shaped_burst(click_n, sr, rng, 3000, 8000)
            loop.add(seconds_to_samples(s / d["rate"], sr), y * float(rng.uniform(0.7, 1.0)))
        return
    n = seconds_to_samples(d["on"], sr)
    t = np.arange(n) / sr
    if style == "twotone":
        f = np.where(np.sin(2 * np.pi * d["rate"] * t) >= 0, d["f1"], d["f2"])
    else:
        f = d["f1"] + (d["f2"] - d["f1"]) * ((t / d["period"]) % 1.0)
    loop.add(0, harmonic_tone(f, n, sr, PIEZO) * ramp_envelope(n, sr, 0.005, 0.01))


# --------------------------------------------------------------------------- furby
FURBY_STYLES = ("babble", "chirp", "giggle", "warble")
# Adult vowel formants (Hz) and bandwidths; a furby's are these scaled up (a small vocal tract).
VOWELS: dict[str, tuple[float, float, float]] = {
    "a": (730, 1090, 2440), "e": (530, 1840, 2480), "i": (270, 2290, 3010),
    "o": (570, 840, 2410), "u": (300, 870, 2240), "ae": (660, 1720, 2410),
}
BANDWIDTHS = (90.0, 120.0, 180.0)


def _syllable(rng: np.random.Generator, t0: float, dur: float, st0: float, vib: tuple[float, float], breath: float,
              consonant: bool) -> dict[str, Any]:
    names = list(VOWELS)
    return {
        "t": t0, "dur": dur,
        "va": names[int(rng.integers(len(names)))], "vb": names[int(rng.integers(len(names)))],
        "contour": (st0 + float(rng.uniform(-3, 3)), st0 + float(rng.uniform(-2, 6)), st0 + float(rng.uniform(-5, 4))),
        "vib": vib, "breath": breath,
        "cons": (float(rng.uniform(1500, 3500)), float(rng.uniform(0.015, 0.035))) if consonant else None,
    }


def _design_furby(k: int, rng: np.random.Generator) -> Design:
    style = FURBY_STYLES[k % len(FURBY_STYLES)]
    voice = {"f0": float(rng.uniform(230, 520)), "fscale": float(rng.uniform(1.15, 1.55)), "slope": float(rng.uniform(1.3, 2.0))}
    breath = float(rng.uniform(0.0, 0.04))
    syl: list[dict[str, Any]] = []
    t = 0.0
    if style == "babble":
        for _ in range(int(rng.integers(1, 3))):
            for _ in range(int(rng.integers(3, 8))):
                dur = float(rng.uniform(0.09, 0.25))
                vib = (float(rng.uniform(5, 9)), float(rng.uniform(0.0, 0.8)))
                syl.append(_syllable(rng, t, dur, float(rng.uniform(-3, 5)), vib, breath, rng.random() < 0.5))
                t += dur + float(rng.uniform(0.01, 0.08))
            t += float(rng.uniform(0.15, 0.35))
    elif style == "giggle":
        period = float(rng.uniform(0.12, 0.2))
        st, step = float(rng.uniform(4, 9)), float(rng.uniform(0.8, 2.0))
        vowel = str(rng.choice(["i", "e", "a", "ae"]))
        for i in range(int(rng.integers(4, 8))):
            s = _syllable(rng, t, float(rng.uniform(0.06, 0.1)), st - i * step, (7.0, 0.0), breath, True)
            s["va"] = s["vb"] = vowel
            s["contour"] = (st - i * step + 1.0, st - i * step, st - i * step - 1.5)
            s["cons"] = (float(rng.uniform(600, 1200)), 0.03)  # the aspirated "h" of "he-he"
            syl.append(s)
            t += period
    elif style == "warble":
        for _ in range(int(rng.integers(1, 3))):
            dur = float(rng.uniform(0.5, 1.1))
            vib = (float(rng.uniform(6, 13)), float(rng.uniform(1.0, 3.0)))
            syl.append(_syllable(rng, t, dur, float(rng.uniform(-2, 4)), vib, breath, rng.random() < 0.3))
            t += dur + float(rng.uniform(0.08, 0.3))
    else:  # chirp: quick squeaks an octave above the speaking voice, swooping up or down
        for _ in range(int(rng.integers(1, 3))):
            for _ in range(int(rng.integers(3, 7))):
                dur = float(rng.uniform(0.05, 0.13))
                s = _syllable(rng, t, dur, 12.0, (9.0, 0.0), breath, False)
                a, b = float(rng.uniform(8, 16)), float(rng.uniform(8, 16))
                s["contour"] = (a, (a + b) / 2 + float(rng.uniform(-3, 3)), b)
                syl.append(s)
                t += dur + float(rng.uniform(0.03, 0.12))
            t += float(rng.uniform(0.15, 0.3))
    pause = float(rng.uniform(0.3, 0.9))
    return {"style": style, "voice": voice, "syllables": syl, "duration": min(4.0, max(1.0, t + pause))}


def _voiced(s: dict[str, Any], voice: dict[str, float], sr: int, rng: np.random.Generator) -> np.ndarray:
    """A syllable: glottal harmonics whose amplitudes follow gliding formants, with a pitch contour and vibrato."""
    n = seconds_to_samples(s["dur"], sr)
    t = np.arange(n) / sr
    w = t / s["dur"]
    c0, c1, c2 = s["contour"]
    st = np.interp(w, [0.0, 0.5, 1.0], [c0, c1, c2]) + s["vib"][1] * np.sin(2 * np.pi * s["vib"][0] * t)
    f0 = voice["f0"] * 2.0 ** (st / 12.0)
    scale = voice["fscale"]
    fa, fb = np.array(VOWELS[s["va"]]) * scale, np.array(VOWELS[s["vb"]]) * scale
    forms = [(fa[i] * (1 - w) + fb[i] * w, BANDWIDTHS[i] * scale, g) for i, g in enumerate((1.0, 0.7, 0.35))]
    slope = voice["slope"]

    def amps(k: int, fk: np.ndarray) -> np.ndarray:
        env = sum(g / (1.0 + ((fk - fc) / (0.5 * bw)) ** 2) for fc, bw, g in forms)
        return k**-slope * (0.01 + env)

    y = harmonic_tone(f0, n, sr, amps)
    peak = float(np.max(np.abs(y))) or 1.0
    y = y / peak
    if s["breath"] > 0:
        y += s["breath"] * shaped_burst(n, sr, rng, 800, 4500)
    y *= ramp_envelope(n, sr, 0.012, 0.03)
    if s["cons"] is not None:
        lo, dur = s["cons"]
        m = seconds_to_samples(dur, sr)
        y = np.concatenate([0.5 * shaped_burst(m, sr, rng, lo, lo * 3), y])
    return y


def _render_furby(d: Design, loop: Loop, sr: int, rng: np.random.Generator) -> None:
    for s in d["syllables"]:
        loop.add(seconds_to_samples(s["t"], sr), _voiced(s, d["voice"], sr, rng))


# --------------------------------------------------------------------------- doorbell
DOORBELL_STYLES = ("dingdong", "threetone", "westminster", "buzzer")
# The five changes of the Westminster quarters, in semitones from the tonic (E F# G# and low B).
WESTMINSTER = ((4, 2, 0, -5), (0, 4, 2, -5), (0, 2, 4, 0), (4, 0, 2, -5), (-5, 2, 4, 0))
CHIMES = {
    "bar": ((1.0, 2.756, 5.404, 8.933), (1.0, 0.5, 0.25, 0.1), (1.0, 0.45, 0.25, 0.12)),
    "bell": ((0.5, 1.0, 1.19, 1.5, 2.0, 2.51), (0.3, 1.0, 0.4, 0.3, 0.25, 0.12), (1.5, 1.0, 0.7, 0.5, 0.4, 0.3)),
    "electronic": ((1.0, 1.003, 2.0, 3.0), (1.0, 0.6, 0.25, 0.08), (1.0, 1.0, 0.5, 0.3)),
}


def _design_doorbell(k: int, rng: np.random.Generator) -> Design:
    style = DOORBELL_STYLES[k % len(DOORBELL_STYLES)]
    if style == "buzzer":
        f = (60.0, 100.0, 120.0, 80.0)[(k // len(DOORBELL_STYLES)) % 4] * float(rng.uniform(0.95, 1.05))
        if (k // len(DOORBELL_STYLES)) % 2 == 0:
            bursts = [(0.0, float(rng.uniform(0.7, 1.4)))]
        else:
            on = float(rng.uniform(0.25, 0.45))
            bursts = [(0.0, on), (on + float(rng.uniform(0.15, 0.3)), on)]
        return {"style": style, "f": f, "res": float(rng.uniform(500, 1600)), "bursts": bursts,
                "duration": float(rng.uniform(2.0, 3.0))}
    timbre = list(CHIMES)[(k // len(DOORBELL_STYLES)) % len(CHIMES)]
    top = int(rng.integers(72, 85))
    if style == "dingdong":
        gap = float(rng.uniform(0.45, 0.8))
        notes = [(0.0, top), (gap, top - (4, 3, 5, 7)[(k // len(DOORBELL_STYLES)) % 4])]
        ring = float(rng.uniform(1.6, 2.6))
    elif style == "threetone":
        gap = float(rng.uniform(0.3, 0.5))
        pattern = [(0, -4, -7), (0, -3, -7), (-7, -3, 0), (-7, -4, 0), (0, -5, -9)][(k // len(DOORBELL_STYLES)) % 5]
        notes = [(i * gap, top + p) for i, p in enumerate(pattern)]
        ring = float(rng.uniform(1.5, 2.4))
    else:
        gap = float(rng.uniform(0.35, 0.55))
        tonic = top - 12
        change = WESTMINSTER[(k // len(DOORBELL_STYLES)) % len(WESTMINSTER)]
        notes = [(i * gap, tonic + p) for i, p in enumerate(change)]
        ring = float(rng.uniform(1.5, 2.1))
    return {"style": style, "timbre": timbre, "T": float(rng.uniform(0.8, 1.5)), "notes": notes,
            "duration": min(4.0, notes[-1][0] + ring)}


def _render_doorbell(d: Design, loop: Loop, sr: int, rng: np.random.Generator) -> None:
    if d["style"] == "buzzer":
        f, res = d["f"], d["res"]

        def amps(k: int, fk: np.ndarray) -> np.ndarray:
            return k**-0.7 * (0.3 + 1.0 / (1.0 + ((fk - res) / (0.25 * res)) ** 2))

        for t0, dur in d["bursts"]:
            n = seconds_to_samples(dur, sr)
            t = np.arange(n) / sr
            rattle = 1.0 + 0.3 * np.sin(2 * np.pi * 2 * f * t)  # the armature chattering on the gong
            y = harmonic_tone(f, n, sr, amps) * rattle * ramp_envelope(n, sr, 0.008, 0.02)
            loop.add(seconds_to_samples(t0, sr), y)
        return
    ratios, amps_, taus = CHIMES[d["timbre"]]
    n = seconds_to_samples(min(5 * d["T"], d["duration"]), sr)
    for t0, midi in d["notes"]:
        f = midi_to_hz(midi)
        y = partials([r * f for r in ratios], amps_, [d["T"] * s for s in taus], n, sr,
                     phases=rng.uniform(0, 2 * np.pi, len(ratios)))
        loop.add(seconds_to_samples(t0, sr), y)


# --------------------------------------------------------------------------- sink
SINK_FLOWS = ("trickle", "steady", "full")


def _design_sink(k: int, rng: np.random.Generator) -> Design:
    flow = SINK_FLOWS[k % len(SINK_FLOWS)]
    rate = {"trickle": (5, 14), "steady": (40, 90), "full": (150, 300)}[flow]
    return {
        "flow": flow,
        "slope": float(rng.uniform(-5.5, -1.0)),  # dB per octave
        "fc": float(np.exp(rng.uniform(np.log(400), np.log(3000)))),
        "width": float(rng.uniform(0.8, 2.0)),  # octaves (std of the log-Gaussian band)
        "rumble": float(rng.uniform(0.0, 0.6)) * (2.0 if flow == "full" else 0.5),
        "am_rate": float(rng.uniform(2, 10)),
        "am_depth": float(rng.uniform(0.1, 0.5)),
        "bubble_rate": float(rng.uniform(*rate)),
        "bubble_band": tuple(sorted(np.exp(rng.uniform(np.log(300), np.log(3500), 2)).tolist())),
        "duration": float(rng.uniform(2.0, 3.5)),
    }


def _render_sink(d: Design, loop: Loop, sr: int, rng: np.random.Generator) -> None:
    flow = d["flow"]
    lo, hi = d["bubble_band"]
    hi = max(hi, lo * 1.5)
    count = int(d["bubble_rate"] * d["duration"])
    # Event draws first (they do not depend on sr), so bubbles sit at the same times at any rate.
    times = rng.uniform(0, d["duration"], count)
    f0s = np.exp(rng.uniform(np.log(lo), np.log(hi), count))
    taus = rng.uniform(0.004, 0.025, count) * (2.0 if flow == "trickle" else 1.0)
    rises = rng.uniform(0.3, 1.0, count)  # pitch rise over a bubble's life (x1.3 .. x2)
    gains = rng.uniform(0.3, 1.0, count)
    for t0, f0, tau, rise, g in zip(times, f0s, taus, rises, gains):
        m = seconds_to_samples(5 * tau, sr)
        t = np.arange(m) / sr
        f = np.minimum(f0 * (1 + rise * t / (5 * tau)), 0.45 * sr)  # a rising bubble's resonance goes up
        y = np.sin(cumulative_phase(f, m, sr)) * decay_envelope(m, sr, tau, attack=0.001)
        loop.add(seconds_to_samples(t0, sr), g * y)
    bubble_rms = float(np.sqrt(np.mean(loop.buf**2))) or 1.0
    n = loop.n
    slope, fc, width, rumble = d["slope"], d["fc"], d["width"], d["rumble"]

    def mag(f: np.ndarray) -> np.ndarray:
        ff = np.maximum(f, 20.0)
        band = np.exp(-0.5 * (np.log2(ff / fc) / width) ** 2)
        low = rumble * np.exp(-0.5 * (ff / 250.0) ** 2)
        return (ff / 1000.0) ** (slope / 6.02) * (band + low) * (ff > 40)

    hiss = circular_noise(n, sr, rng, mag)
    am = np.clip(1.0 + d["am_depth"] * smooth_periodic(n, sr, rng, d["am_rate"]), 0.05, None)
    level = {"trickle": 0.25, "steady": 1.0, "full": 2.5}[flow]
    loop.buf += level * bubble_rms * hiss * am


_DESIGNERS: dict[str, Callable[[int, np.random.Generator], Design]] = {
    "phone": _design_phone, "alarm": _design_alarm, "furby": _design_furby, "doorbell": _design_doorbell, "sink": _design_sink,
}
_RENDERERS: dict[str, Callable[[Design, Loop, int, np.random.Generator], None]] = {
    "phone": _render_phone, "alarm": _render_alarm, "furby": _render_furby, "doorbell": _render_doorbell, "sink": _render_sink,
}
