#!/usr/bin/env python3
"""Writes materials/default.json, earshot's built-in acoustic materials.

Every value's origin is recorded in the material's "source" string and in
materials/README.md. Absorption tables come from three openly licensed sets
(copies of their licences are in materials/):

  PRA   pyroomacoustics materials table (MIT), values from M. Vorlaender,
        "Auralization", Springer 2008, appendix (octave bands 125 Hz-8 kHz;
        rows with 6 values stop at 4 kHz and are held constant to 8 kHz).
  RA    Resonance Audio, Utils.ROOM_MATERIAL_COEFFICIENTS (Apache-2.0),
        9 octave bands 31.25 Hz-8 kHz; only the 125 Hz-8 kHz values are used.
  STEAM Steam Audio material presets (Apache-2.0), 3 bands centred at
        400 Hz, 2.5 kHz and 15 kHz, interpolated to octave bands linearly in
        log-frequency and held constant beyond the end centres (the same rule
        the earshot loader applies).

Transmission follows the engine's convention: tau is the part of the
absorbed energy alpha that passes through the surface, so tau <= alpha.
Values that would break this are clamped to alpha (said in the source).
Mass-law transmission uses the field-incidence mass law
R = 20 log10(m f) - 47 dB (Bies & Hansen, "Engineering Noise Control",
ch. 7), i.e. tau = 10^4.7 / (m f)^2, ignoring coincidence dips.

Scattering coefficients (ISO 17497-1 definition) are engineering estimates
unless a table is named: smooth massive surfaces 0.05, finished but
non-planar surfaces 0.1-0.2, rough or granular ground 0.3-0.5, seat rows and
audiences per Vorlaender's tables (PRA "scattering").

Usage: python3 tools/make_default_materials.py [OUTPUT.json]
"""
import json
import math
import os
import sys

BANDS = [125, 250, 500, 1000, 2000, 4000, 8000]


def hold8k(values):
    """A 6-value 125 Hz-4 kHz row, extended to 8 kHz by holding 4 kHz."""
    assert len(values) in (6, 7)
    return list(values) + [values[-1]] * (7 - len(values))


def steam(values3):
    """Steam Audio 3-band values (400, 2500, 15000 Hz) -> 7 octave bands."""
    centres = [400.0, 2500.0, 15000.0]
    out = []
    for f in BANDS:
        if f <= centres[0]:
            v = values3[0]
        elif f >= centres[-1]:
            v = values3[-1]
        else:
            i = 0 if f < centres[1] else 1
            t = math.log(f / centres[i]) / math.log(centres[i + 1] / centres[i])
            v = values3[i] + t * (values3[i + 1] - values3[i])
        out.append(round(v, 4))
    return out


def mass_law(mass_kg_m2):
    return [float(f"{min(1.0, 10 ** 4.7 / (mass_kg_m2 * f) ** 2):.3g}") for f in BANDS]


def clamp_to(tau, alpha):
    return [min(t, a) for t, a in zip(tau, alpha)]


SMOOTH = "scattering 0.05: engineering estimate for a smooth massive surface"

# name: (absorption, scattering, transmission or None, source text)
M = {}


def add(name, absorption, scattering, transmission, source):
    assert len(absorption) == 7, name
    if transmission is not None:
        assert all(t <= a + 1e-12 for t, a in zip(transmission, absorption)), name
    M[name] = (absorption, scattering, transmission, source)


generic = steam([0.10, 0.20, 0.30])
add("default", generic, 0.1, None,
    "absorption: STEAM 'generic' preset (interpolated); no transmission (an unmapped surface "
    "should not leak); scattering 0.1: engineering estimate. A moderate generic surface for "
    "anything not mapped to a material.")

add("concrete", [0.01, 0.01, 0.02, 0.02, 0.02, 0.05, 0.05], 0.05, None,
    "absorption: PRA 'unpainted_concrete' (smooth unpainted concrete, Vorlaender); " + SMOOTH)
add("concrete_rough", [0.02, 0.03, 0.03, 0.03, 0.04, 0.07, 0.07], 0.2, None,
    "absorption: PRA 'rough_concrete' (Vorlaender); scattering 0.2: engineering estimate")
add("concrete_block_painted", [0.10, 0.05, 0.06, 0.07, 0.09, 0.08, 0.16], 0.1, None,
    "absorption: RA 'concrete-block-painted'; scattering 0.1: engineering estimate")
add("brick", [0.03, 0.03, 0.03, 0.04, 0.05, 0.07, 0.14], 0.15, None,
    "absorption: RA 'brick-bare'; scattering 0.15: engineering estimate (mortar joints)")
add("brick_painted", [0.01, 0.01, 0.02, 0.02, 0.02, 0.03, 0.06], 0.1, None,
    "absorption: RA 'brick-painted'; scattering 0.1: engineering estimate")
add("plaster", [0.013, 0.015, 0.02, 0.03, 0.04, 0.05, 0.10], 0.05, None,
    "absorption: RA 'plaster-smooth'; " + SMOOTH)
add("plaster_rough", [0.02, 0.03, 0.04, 0.05, 0.04, 0.03, 0.06], 0.1, None,
    "absorption: RA 'plaster-rough'; scattering 0.1: engineering estimate")
gypsum = [0.15, 0.10, 0.06, 0.04, 0.04, 0.05, 0.05]
add("gypsum_board", gypsum, 0.05, mass_law(20.0),
    "absorption: PRA 'plasterboard' (2 x 13 mm on steel frame, mineral wool in cavity, "
    "Vorlaender); transmission: field-incidence mass law for 20 kg/m2 (cavity and coincidence "
    "ignored); " + SMOOTH)
add("ceiling_plasterboard", hold8k([0.20, 0.15, 0.10, 0.08, 0.04, 0.02]), 0.05, None,
    "absorption: PRA 'ceiling_plasterboard' (on battens, large air space above, Vorlaender; "
    "4 kHz value held to 8 kHz); " + SMOOTH)
add("wood_panel", [0.28, 0.22, 0.17, 0.09, 0.10, 0.11, 0.22], 0.1, None,
    "absorption: RA 'wood-panel'; scattering 0.1: engineering estimate")
add("wood_floor", [0.04, 0.04, 0.07, 0.06, 0.06, 0.07, 0.14], 0.05, None,
    "absorption: RA 'parquet-on-concrete'; " + SMOOTH)
add("stage_floor", hold8k([0.10, 0.07, 0.06, 0.06, 0.06, 0.06]), 0.05, None,
    "absorption: PRA 'stage_floor' (2 layers 27 mm over air space, Vorlaender; 4 kHz value "
    "held to 8 kHz); " + SMOOTH)
door = [0.14, 0.10, 0.06, 0.08, 0.10, 0.10, 0.10]
add("door_wood", door, 0.05, clamp_to(steam([0.07, 0.014, 0.005]), door),
    "absorption: PRA 'wooden_door' (solid wooden door, Vorlaender); transmission: STEAM 'wood' "
    "preset (interpolated; clamped to absorption where larger); " + SMOOTH)
window = [0.10, 0.05, 0.04, 0.03, 0.03, 0.03, 0.03]
add("glass_window", window, 0.05, clamp_to(mass_law(10.0), window),
    "absorption: PRA 'glass_window' (0.68 kg/m2 per Vorlaender's table); transmission: mass law "
    "for a 4 mm pane, 10 kg/m2 (coincidence dip ignored); " + SMOOTH)
heavy = [0.18, 0.06, 0.04, 0.03, 0.02, 0.02, 0.04]
add("glass_heavy", heavy, 0.05, clamp_to(mass_law(25.0), heavy),
    "absorption: RA 'glass-thin' row (its values match the classic table entry for large panes "
    "of heavy plate glass); transmission: mass law for 10 mm glass, 25 kg/m2; " + SMOOTH)
dg = [0.15, 0.05, 0.03, 0.03, 0.02, 0.02, 0.02]
add("double_glazing", dg, 0.05, clamp_to(mass_law(40.0), dg),
    "absorption: PRA 'double_glazing_30mm' (Vorlaender); transmission: engineering estimate, "
    "mass law for the total 40 kg/m2 (the cavity's extra insulation ignored); " + SMOOTH)
add("carpet_thin", hold8k([0.02, 0.04, 0.08, 0.20, 0.35, 0.40]), 0.1, None,
    "absorption: PRA 'carpet_thin' (cemented to concrete, Vorlaender; 4 kHz held to 8 kHz); "
    "scattering 0.1: engineering estimate")
add("carpet_thick", [0.08, 0.08, 0.30, 0.60, 0.75, 0.80, 0.80], 0.1, None,
    "absorption: PRA 'carpet_tufted_9m' (9 mm tufted pile on felt underlay, Vorlaender); "
    "scattering 0.1: engineering estimate")
light = [0.05, 0.06, 0.39, 0.63, 0.70, 0.73, 0.73]
add("curtain_light", light, 0.1, [round(0.5 * a, 4) for a in light],
    "absorption: PRA 'curtains_0.2' (0.2 kg/m2 hung 90 mm from wall, Vorlaender); transmission: "
    "engineering estimate, half the absorbed energy passes a light curtain; scattering 0.1: "
    "engineering estimate")
heavyc = [0.30, 0.45, 0.65, 0.56, 0.59, 0.71, 0.71]
add("curtain_heavy", heavyc, 0.15, [round(0.25 * a, 4) for a in heavyc],
    "absorption: PRA 'curtains_cotton_0.5' (0.5 kg/m2 draped to 3/4 area, Vorlaender); "
    "transmission: engineering estimate, a quarter of the absorbed energy passes a heavy "
    "curtain; scattering 0.15: engineering estimate (folds)")
add("acoustic_ceiling_tile", hold8k([0.49, 0.53, 0.53, 0.75, 0.92, 0.99]), 0.1, None,
    "absorption: PRA 'ceiling_fissured_tile' (Vorlaender; 4 kHz held to 8 kHz); scattering 0.1: "
    "engineering estimate")
add("rockwool", [0.22, 0.60, 0.92, 0.90, 0.88, 0.88, 0.88], 0.1, None,
    "absorption: PRA 'rockwool_50mm_80kgm3' (50 mm, 80 kg/m3, Vorlaender); scattering 0.1: "
    "engineering estimate")
add("fabric_panel", [0.46, 0.93, 1.0, 1.0, 1.0, 1.0, 1.0], 0.1, None,
    "absorption: PRA 'panel_fabric_covered_6pcf' (fabric-covered rockwool panel, Vorlaender); "
    "scattering 0.1: engineering estimate")
add("foam", hold8k([0.12, 0.33, 0.83, 0.97, 0.98, 0.95]), 0.2, None,
    "absorption: PRA 'ceiling_melamine_foam' (wedge-shaped melamine foam, Vorlaender; 4 kHz held "
    "to 8 kHz); scattering 0.2: engineering estimate (wedges)")
add("fibreglass", [0.22, 0.82, 0.99, 0.99, 0.99, 0.99, 1.0], 0.1, None,
    "absorption: RA 'fiber-glass-insulation'; scattering 0.1: engineering estimate")
theatre_s = [0.3, 0.5, 0.6, 0.6, 0.7, 0.7, 0.7]
add("audience", hold8k([0.72, 0.82, 0.91, 0.93, 0.94, 0.87]), theatre_s, None,
    "absorption: PRA 'audience_upholstered_chairs_1' (audience in moderately upholstered chairs, "
    "Vorlaender; 4 kHz held to 8 kHz); scattering: PRA scattering 'theatre_audience' (Vorlaender)")
add("seats_upholstered", [0.44, 0.60, 0.77, 0.89, 0.82, 0.70, 0.70], theatre_s, None,
    "absorption: PRA 'chairs_upholstered_cloth' (empty, cloth cover, Vorlaender); scattering: PRA "
    "scattering 'theatre_audience' (Vorlaender), used for rows of seats")
add("chairs_wooden", hold8k([0.05, 0.08, 0.10, 0.12, 0.12, 0.12]),
    [0.2, 0.3, 0.4, 0.5, 0.5, 0.6, 0.6], None,
    "absorption: PRA 'chairs_wooden' (2 per m2, Vorlaender; 4 kHz held to 8 kHz); scattering: PRA "
    "scattering 'classroom_tables' (Vorlaender)")
add("water", [0.008, 0.008, 0.013, 0.015, 0.02, 0.025, 0.05], 0.02, None,
    "absorption: RA 'water-or-ice-surface'; scattering 0.02: engineering estimate (calm surface)")
add("grass", [0.15, 0.25, 0.40, 0.55, 0.60, 0.60, 0.60], 0.4, None,
    "absorption: RA 'grass'; scattering 0.4: engineering estimate")
add("soil", [0.15, 0.25, 0.40, 0.55, 0.60, 0.60, 0.60], 0.3, None,
    "absorption: engineering estimate (the referenced tables have no soil row), taken equal to "
    "RA 'grass' as both are porous ground; scattering 0.3: engineering estimate")
add("gravel", steam([0.60, 0.70, 0.80]), 0.5, None,
    "absorption: STEAM 'gravel' preset (interpolated); scattering 0.5: engineering estimate "
    "(granular surface)")
add("rock", steam([0.13, 0.20, 0.24]), 0.3, None,
    "absorption: STEAM 'rock' preset (interpolated); scattering 0.3: engineering estimate")
add("metal", [0.04, 0.04, 0.05, 0.05, 0.05, 0.07, 0.09], 0.05, None,
    "absorption: RA 'metal'; " + SMOOTH)
add("marble", [0.01, 0.01, 0.01, 0.01, 0.02, 0.02, 0.04], 0.05, None,
    "absorption: RA 'marble'; " + SMOOTH)
add("ceramic_tile", [0.01, 0.01, 0.01, 0.02, 0.02, 0.02, 0.02], 0.05, None,
    "absorption: PRA 'ceramic_tiles' (smooth surface, Vorlaender); " + SMOOTH)
add("linoleum", [0.02, 0.03, 0.03, 0.03, 0.03, 0.02, 0.04], 0.05, None,
    "absorption: RA 'linoleum-on-concrete'; " + SMOOTH)
add("transparent", [1.0] * 7, 0.0, [1.0] * 7,
    "RA 'transparent': an open portal, everything passes through (alpha = tau = 1)")


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    out = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "materials", "default.json")
    mats = {}
    for name, (a, s, t, src) in M.items():
        entry = {"absorption": a, "scattering": s}
        if t is not None:
            entry["transmission"] = t
        entry["source"] = src
        mats[name] = entry
    doc = {
        "description": "earshot default acoustic materials. Generated by tools/make_default_materials.py; "
                       "see materials/README.md for the sources and their licences.",
        "bands_hz": BANDS,
        "materials": mats,
    }
    # One material per line block, arrays on one line: readable diffs.
    lines = ["{"]
    lines.append(f'  "description": {json.dumps(doc["description"])},')
    lines.append(f'  "bands_hz": {json.dumps(BANDS)},')
    lines.append('  "materials": {')
    names = list(mats)
    for i, name in enumerate(names):
        e = mats[name]
        fields = [f'      "{k}": {json.dumps(v)}' for k, v in e.items()]
        comma = "," if i + 1 < len(names) else ""
        lines.append(f'    {json.dumps(name)}: {{\n' + ",\n".join(fields) + f"\n    }}{comma}")
    lines.append("  }")
    lines.append("}")
    text = "\n".join(lines) + "\n"
    json.loads(text)
    with open(out, "w", encoding="utf-8") as f:
        f.write(text)
    print(f"wrote {out}: {len(mats)} materials")


if __name__ == "__main__":
    main()
