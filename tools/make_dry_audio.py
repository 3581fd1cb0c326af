#!/usr/bin/env python3
"""Synthesises the dry (anechoic) test signals of the sample scenes (samples/dry_audio.md).

Pure Python 3 standard library (no numpy), seeded, so the files can be
remade at will; mono 16-bit PCM WAV, peak -1 dBFS, each under 1 MB:

  guitar.wav  44.1 kHz, 10 s  plucked-string melody (Karplus-Strong with
                              all-pass tuning, notes left ringing)
  claps.wav   44.1 kHz, 11 s  percussion loop at 120 BPM: kick on 1 and 3,
                              hand claps on 2 and 4, wood-block eighths
  voice.wav   48 kHz,    9 s  speech-like syllables: a glottal pulse train
                              (Rosenberg shape) through four formant
                              resonators gliding between vowels, with
                              nasal, fricative and plosive consonants

44.1 kHz files exercise the renderer's resampling (scenes run at 48 kHz).
References: K. Karplus and A. Strong, "Digital synthesis of plucked-string
and drum timbres", CMJ 7(2), 1983; D. Jaffe and J. O. Smith, "Extensions of
the Karplus-Strong plucked-string algorithm", CMJ 7(2), 1983; A. E.
Rosenberg, "Effect of glottal pulse shape on the quality of natural vowels",
JASA 49, 1971; D. H. Klatt, "Software for a cascade/parallel formant
synthesizer", JASA 67(3), 1980 (resonators); G. E. Peterson and H. L.
Barney, JASA 24, 1952 (vowel formants).

Usage: python3 tools/make_dry_audio.py [OUT_DIR]   (default: each scene's folder under samples/)
"""
import math
import os
import random
import struct
import sys
import wave

PEAK = 10 ** (-1 / 20)  # -1 dBFS


def write_wav(path, rate, samples):
    """Normalises to PEAK and writes mono 16-bit PCM."""
    peak = max(abs(s) for s in samples) or 1.0
    g = PEAK / peak
    frames = bytearray()
    for s in samples:
        frames += struct.pack("<h", max(-32767, min(32767, int(round(s * g * 32767)))))
    with wave.open(path, "wb") as w:
        w.setnchannels(1)
        w.setsampwidth(2)
        w.setframerate(rate)
        w.writeframes(bytes(frames))
    print(f"{os.path.normpath(path)}: {rate} Hz, {len(samples) / rate:.2f} s, {os.path.getsize(path)} bytes")


def midi_hz(note):
    return 440.0 * 2 ** ((note - 69) / 12)


class Resonator:
    """Klatt two-pole resonator with unity gain at DC."""

    def __init__(self, rate, hz, bw):
        self.rate = rate
        self.y1 = self.y2 = 0.0
        self.set(hz, bw)

    def set(self, hz, bw):
        r = math.exp(-math.pi * bw / self.rate)
        self.b1 = 2 * r * math.cos(2 * math.pi * hz / self.rate)
        self.b2 = -r * r
        self.a0 = 1 - self.b1 - self.b2

    def __call__(self, x):
        y = self.a0 * x + self.b1 * self.y1 + self.b2 * self.y2
        self.y2, self.y1 = self.y1, y
        return y


def bandpass(rate, hz, q):
    """RBJ band-pass biquad (constant 0 dB peak gain) as a closure."""
    w = 2 * math.pi * hz / rate
    alpha = math.sin(w) / (2 * q)
    a0 = 1 + alpha
    b0, b2 = alpha / a0, -alpha / a0
    a1, a2 = -2 * math.cos(w) / a0, (1 - alpha) / a0
    state = [0.0, 0.0, 0.0, 0.0]  # x1, x2, y1, y2

    def f(x):
        y = b0 * x + b2 * state[1] - a1 * state[2] - a2 * state[3]
        state[1], state[0] = state[0], x
        state[3], state[2] = state[2], y
        return y

    return f


# ---------------------------------------------------------------- guitar

def pluck(rate, hz, seconds, rng, brightness=0.5, decay=0.996):
    """One Karplus-Strong note: a noise-filled delay line with a two-point
    average in the loop and a first-order all-pass for the fractional part
    of the period (Jaffe & Smith)."""
    period = rate / hz - 0.5  # the averaging filter delays half a sample
    n = int(period)
    frac = period - n
    if frac < 0.1:  # keep the all-pass coefficient well inside (-1, 1)
        n -= 1
        frac += 1
    c = (1 - frac) / (1 + frac)
    # Initial excitation: noise, softened by a one-pole low-pass (brightness).
    buf, lp = [], 0.0
    for _ in range(n):
        lp += brightness * ((2 * rng.random() - 1) - lp)
        buf.append(lp)
    mean = sum(buf) / n
    buf = [b - mean for b in buf]
    out = []
    idx, prev, ap_x1, ap_y1 = 0, 0.0, 0.0, 0.0
    for _ in range(int(seconds * rate)):
        x = buf[idx]
        avg = decay * 0.5 * (x + prev)
        prev = x
        y = c * avg + ap_x1 - c * ap_y1  # all-pass
        ap_x1, ap_y1 = avg, y
        buf[idx] = y
        idx = (idx + 1) % n
        out.append(x)
    return out


def guitar(rate=44100, seconds=10.0):
    rng = random.Random(7)
    beat = 60.0 / 96  # 96 BPM
    # (start beat, MIDI note, beats): an A-minor arpeggiated melody.
    melody = []
    arps = [(57, 60, 64, 69), (53, 57, 60, 65), (48, 52, 55, 60), (52, 56, 59, 64)]
    tune = [76, 74, 72, 71, 72, 74, 76, 79, 77, 76, 74, 72, 71, 72, 69, 69]
    for bar, chord in enumerate(arps * 1):
        for k in range(8):
            melody.append((bar * 4 + k * 0.5, chord[k % 4] - 12 if k == 0 else chord[k % 4], 2.0))
    for i, note in enumerate(tune):
        melody.append((i * 1.0, note, 1.5))
    total = int(seconds * rate)
    mix = [0.0] * total
    for start, note, beats in melody:
        s0 = int(start * beat * rate)
        if s0 >= total:
            continue
        ring = min(beats * beat + 1.2, seconds - start * beat)
        gain = 0.8 if note < 60 else 1.0
        bright = 0.35 if note < 60 else 0.6
        tone = pluck(rate, midi_hz(note), ring, rng, brightness=bright)
        # Short release so notes do not stop with a click at the end.
        fade = int(0.05 * rate)
        for i, v in enumerate(tone):
            j = s0 + i
            if j >= total:
                break
            env = min(1.0, (len(tone) - i) / fade)
            mix[j] += gain * env * v
    return mix


# ---------------------------------------------------------------- claps

def claps(rate=44100, seconds=11.0):
    rng = random.Random(11)
    total = int(seconds * rate)
    mix = [0.0] * total
    beat = 0.5  # 120 BPM

    def add(s0, sig):
        for i, v in enumerate(sig):
            if s0 + i < total:
                mix[s0 + i] += v

    def kick():
        out, phase = [], 0.0
        for i in range(int(0.35 * rate)):
            t = i / rate
            hz = 45 + 90 * math.exp(-t / 0.04)
            phase += 2 * math.pi * hz / rate
            out.append(0.5 * math.exp(-t / 0.12) * math.sin(phase))
        return out

    def clap():
        # Three quick bursts and a longer tail of band-passed noise.
        bp = bandpass(rate, 1200, 1.2)
        out = []
        bursts = (0.0, 0.011, 0.023)
        for i in range(int(0.25 * rate)):
            t = i / rate
            env = sum(math.exp(-(t - b) / 0.004) for b in bursts if t >= b) * 0.6
            if t >= bursts[-1]:
                env += 0.5 * math.exp(-(t - bursts[-1]) / 0.05)
            out.append(bp(env * (2 * rng.random() - 1)) * 5.0)
        return out

    def block(hz):
        return [0.35 * math.exp(-(i / rate) / 0.018) * math.sin(2 * math.pi * hz * i / rate)
                for i in range(int(0.12 * rate))]

    n_beats = int(seconds / beat)
    for b in range(n_beats):
        s = int(b * beat * rate)
        if b % 4 in (0, 2):
            add(s, kick())
        else:
            add(s, clap())
        add(s + int(beat / 2 * rate), block(1850 if b % 2 else 1400))
    return mix


# ---------------------------------------------------------------- voice

VOWELS = {  # F1, F2, F3 (Hz), adult male
    "a": (730, 1090, 2440), "e": (530, 1840, 2480), "i": (270, 2290, 3010),
    "o": (570, 840, 2410), "u": (300, 870, 2240),
}
NASAL = (250, 1200, 2500)


def voice(rate=48000, seconds=9.0):
    rng = random.Random(3)
    # Phrases of syllables (consonant, vowel, seconds); None: a pause.
    phrases = [
        [("m", "a", 0.30), ("r", "i", 0.22), ("s", "o", 0.28), ("l", "u", 0.34)],
        None,
        [("t", "e", 0.22), ("n", "a", 0.26), ("k", "o", 0.24), ("s", "i", 0.30), ("m", "a", 0.40)],
        None,
        [("l", "o", 0.25), ("t", "i", 0.2), ("n", "e", 0.28), ("s", "u", 0.26), ("k", "a", 0.42)],
        None,
        [("m", "i", 0.24), ("r", "a", 0.3), ("t", "o", 0.22), ("n", "u", 0.26), ("s", "e", 0.45)],
    ]
    # Build a timeline of segments: (kind, seconds, vowel or None).
    segments = [("pause", 0.3, None)]
    for ph in phrases:
        if ph is None:
            segments.append(("pause", 0.45, None))
            continue
        for cons, vow, dur in ph:
            if cons in "mn":
                segments.append(("nasal", 0.07, vow))
            elif cons in "lr":
                segments.append(("liquid", 0.05, vow))
            elif cons == "s":
                segments.append(("fric", 0.11, vow))
            else:
                segments.append(("stop", 0.05, vow))
            segments.append(("vowel", dur, vow))
    total = int(seconds * rate)
    out = [0.0] * total
    res = [Resonator(rate, f, b) for f, b in ((500, 60), (1500, 90), (2500, 120), (3500, 150))]
    hiss = bandpass(rate, 5200, 1.5)
    burst = bandpass(rate, 3500, 1.0)
    formants = list(VOWELS["a"])
    phase, n = 0.0, 0
    prev_glottal = 0.0
    phrase_pos = 0.0
    for kind, dur, vow in segments:
        count = int(dur * rate)
        target = NASAL if kind == "nasal" else (VOWELS[vow] if vow else formants)
        for i in range(count):
            if n >= total:
                break
            t = n / rate
            x = i / count
            # Formants glide towards the target (about 30 ms time constant).
            k = 1 - math.exp(-1 / (0.03 * rate))
            for j in range(3):
                formants[j] += k * (target[j] - formants[j])
            if n % 64 == 0:
                for j in range(3):
                    res[j].set(formants[j], (60, 90, 120)[j])
            # Pitch: a falling phrase contour with slow vibrato.
            phrase_pos = phrase_pos + 1 / rate if kind != "pause" else 0.0
            f0 = 135 - 25 * min(1.0, phrase_pos / 2.0) + 3 * math.sin(2 * math.pi * 5.2 * t)
            phase += f0 / rate
            phase -= math.floor(phase)
            # Rosenberg glottal flow, then its derivative (flow derivative x radiation).
            if phase < 0.4:
                g = 0.5 * (1 - math.cos(math.pi * phase / 0.4))
            elif phase < 0.56:
                g = math.cos(math.pi * (phase - 0.4) / 0.32)
            else:
                g = 0.0
            dg = (g - prev_glottal) * rate / 1000.0
            prev_glottal = g
            voiced = {"vowel": 1.0, "nasal": 0.35, "liquid": 0.6, "fric": 0.0, "stop": 0.0}.get(kind, 0.0)
            env = 1.0
            if kind == "vowel":
                env = min(1.0, x / 0.08) * min(1.0, (1 - x) / 0.2)
            elif kind == "pause":
                voiced = 0.0
            y = voiced * env * dg
            for r in res:
                y = r(y)
            noise = 2 * rng.random() - 1
            if kind == "fric":
                y += 0.5 * math.sin(math.pi * x) * hiss(noise)
            elif kind == "stop":
                y += (0.9 * math.exp(-x * 6) if x > 0.5 else 0.0) * burst(noise)
            out[n] = y
            n += 1
    return out


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    samples = os.path.join(here, "..", "samples")
    # Each scene's audio lives in the scene's own folder: file references may
    # not leave it (README, "Untrusted input").
    if len(sys.argv) > 1:
        places = {name: [sys.argv[1]] for name in ("guitar", "claps", "voice")}
    else:
        places = {"guitar": [os.path.join(samples, "hall")],
                  "claps": [os.path.join(samples, "outdoor")],
                  "voice": [os.path.join(samples, "two_rooms"), os.path.join(samples, "shoebox")]}
    made = {"guitar": (44100, guitar), "claps": (44100, claps), "voice": (48000, voice)}
    for name, folders in places.items():
        rate, make = made[name]
        samples_ = make()
        for folder in folders:
            os.makedirs(folder, exist_ok=True)
            write_wav(os.path.join(folder, name + ".wav"), rate, samples_)


if __name__ == "__main__":
    main()
