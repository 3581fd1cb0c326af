#!/usr/bin/env python3
"""Generates earshot's sample scenes under samples/ (glTF + materials_map.json).

Conventions: metres, z is up (as in the reference shoebox
[0,10]x[0,7]x[0,3] of ../shared/reference), room surfaces face into the room,
furniture is closed with outward faces and floats 2 mm above the floor so no
face is coplanar with another. Every glTF material name appears in the
sample's materials_map.json, which maps it to a material of
materials/default.json. Pure Python 3, no dependencies.

Usage: python3 tools/make_sample_scenes.py [SAMPLES_DIR]
"""
import json
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from gltf_writer import Gltf  # noqa: E402

LIFT = 0.002  # furniture clearance above the floor, metres


class Geometry:
    """Triangles grouped by glTF material name."""

    def __init__(self):
        self.parts = {}  # material -> (points, tris)

    def _part(self, material):
        return self.parts.setdefault(material, ([], []))

    def add(self, material, points, tris):
        pts, out = self._part(material)
        base = len(pts)
        pts.extend(points)
        out.extend((a + base, b + base, c + base) for a, b, c in tris)

    def quad(self, material, a, b, c, d):
        """Quad a-b-c-d, counter-clockwise seen from the side its normal faces."""
        self.add(material, [a, b, c, d], [(0, 1, 2), (0, 2, 3)])

    def box(self, material, lo, hi, inward=False):
        x0, y0, z0 = lo
        x1, y1, z1 = hi
        p = [(x0 if i & 1 == 0 else x1, y0 if i & 2 == 0 else y1, z0 if i & 4 == 0 else z1) for i in range(8)]
        # Outward-facing quads (counter-clockwise seen from outside).
        quads = [(0, 4, 6, 2), (1, 3, 7, 5), (0, 1, 5, 4), (2, 6, 7, 3), (0, 2, 3, 1), (4, 5, 7, 6)]
        tris = []
        for q in quads:
            t = [(q[0], q[1], q[2]), (q[0], q[2], q[3])]
            tris += [(a, c, b) for a, b, c in t] if inward else t
        self.add(material, p, tris)

    def cylinder(self, material, centre, radius, height, segments=16):
        """Closed vertical cylinder standing on centre (x, y, z)."""
        cx, cy, cz = centre
        pts = [(cx, cy, cz), (cx, cy, cz + height)]
        for i in range(segments):
            a = 2 * math.pi * i / segments
            x, y = cx + radius * math.cos(a), cy + radius * math.sin(a)
            pts += [(x, y, cz), (x, y, cz + height)]
        tris = []
        for i in range(segments):
            j = (i + 1) % segments
            b0, t0, b1, t1 = 2 + 2 * i, 3 + 2 * i, 2 + 2 * j, 3 + 2 * j
            tris += [(b0, b1, t1), (b0, t1, t0), (0, b1, b0), (1, t0, t1)]
        self.add(material, pts, tris)

    def sphere(self, material, centre, radius, stacks, slices):
        cx, cy, cz = centre
        pts = [(cx, cy, cz - radius), (cx, cy, cz + radius)]
        for s in range(1, stacks):
            phi = math.pi * s / stacks - math.pi / 2
            for k in range(slices):
                th = 2 * math.pi * k / slices
                pts.append((cx + radius * math.cos(phi) * math.cos(th), cy + radius * math.cos(phi) * math.sin(th),
                            cz + radius * math.sin(phi)))
        ring = lambda s, k: 2 + (s - 1) * slices + k % slices  # noqa: E731
        tris = []
        for k in range(slices):
            tris.append((0, ring(1, k + 1), ring(1, k)))
            tris.append((1, ring(stacks - 1, k), ring(stacks - 1, k + 1)))
        for s in range(1, stacks - 1):
            for k in range(slices):
                a, b, c, d = ring(s, k), ring(s, k + 1), ring(s + 1, k + 1), ring(s + 1, k)
                tris += [(a, b, c), (a, c, d)]
        self.add(material, pts, tris)

    def triangle_count(self):
        return sum(len(t) for _, t in self.parts.values())

    def to_gltf(self, g, mesh_name, colors=None):
        prims = []
        for material, (pts, tris) in self.parts.items():
            color = (colors or {}).get(material, (0.8, 0.8, 0.8))
            prims.append(g.primitive([tuple(round(c, 6) for c in p) for p in pts], tris, g.material(material, color=color)))
        return g.mesh(mesh_name, prims)


def wall_with_opening(geo, material, axis_pos, axis, u_range, z_range, hole_u, hole_z, facing, hole_material=None):
    """A vertical wall in the plane x = axis_pos (axis 'x') or y = axis_pos
    (axis 'y'), spanning u_range along the other horizontal axis and z_range,
    split on a grid around the rectangular hole (hole_u x hole_z); the hole is
    left open or filled with hole_material. facing = +1/-1: the normal's sign
    along the wall's axis."""
    us = sorted(set([u_range[0], hole_u[0], hole_u[1], u_range[1]]))
    zs = sorted(set([z_range[0], hole_z[0], hole_z[1], z_range[1]]))

    def pt(u, z):
        return (axis_pos, u, z) if axis == "x" else (u, axis_pos, z)

    for i in range(len(us) - 1):
        for k in range(len(zs) - 1):
            u0, u1, z0, z1 = us[i], us[i + 1], zs[k], zs[k + 1]
            in_hole = hole_u[0] <= u0 and u1 <= hole_u[1] and hole_z[0] <= z0 and z1 <= hole_z[1]
            mat = hole_material if in_hole else material
            if mat is None:
                continue
            a, b, c, d = pt(u0, z0), pt(u1, z0), pt(u1, z1), pt(u0, z1)
            # For axis 'x' the (u, z) = (y, z) frame has normal +x; for 'y' (x, z) has -y.
            sign = facing if axis == "x" else -facing
            if sign > 0:
                geo.quad(mat, a, b, c, d)
            else:
                geo.quad(mat, a, d, c, b)


def write_map(directory, mapping):
    with open(os.path.join(directory, "materials_map.json"), "w", encoding="utf-8") as f:
        json.dump(mapping, f, indent=2, sort_keys=True)
        f.write("\n")


# ---------------------------------------------------------------------------


def shoebox(out):
    """The reference room [0,10]x[0,7]x[0,3], one glTF material per wall,
    faces in makeBox's order west, east, south, north, floor, ceiling."""
    g = Gltf()
    L, W, H = 10.0, 7.0, 3.0
    faces = {
        "west": [(0, 0, 0), (0, W, 0), (0, W, H), (0, 0, H)],
        "east": [(L, 0, 0), (L, 0, H), (L, W, H), (L, W, 0)],
        "south": [(0, 0, 0), (0, 0, H), (L, 0, H), (L, 0, 0)],
        "north": [(0, W, 0), (L, W, 0), (L, W, H), (0, W, H)],
        "floor": [(0, 0, 0), (L, 0, 0), (L, W, 0), (0, W, 0)],
        "ceiling": [(0, 0, H), (0, W, H), (L, W, H), (L, 0, H)],
    }
    prims = [g.primitive(pts, [(0, 1, 2), (0, 2, 3)], g.material(name)) for name, pts in faces.items()]
    g.scene([g.node(name="room", mesh=g.mesh("room", prims))])
    g.write_gltf(os.path.join(out, "shoebox.gltf"))
    write_map(out, {"west": "brick", "east": "plaster", "south": "wood_panel", "north": "gypsum_board",
                    "floor": "carpet_thick", "ceiling": "acoustic_ceiling_tile"})
    return 12


def furnished_room(out):
    L, W, H = 10.0, 7.0, 3.0
    geo = Geometry()
    # Shell: floor, ceiling, three plain walls, a south wall with a window.
    geo.quad("floor_parquet", (0, 0, 0), (L, 0, 0), (L, W, 0), (0, W, 0))
    geo.quad("ceiling_tiles", (0, 0, H), (0, W, H), (L, W, H), (L, 0, H))
    geo.quad("walls_plaster", (0, 0, 0), (0, W, 0), (0, W, H), (0, 0, H))  # west, faces +x
    geo.quad("walls_plaster", (L, 0, 0), (L, 0, H), (L, W, H), (L, W, 0))  # east, faces -x
    geo.quad("walls_plaster", (0, W, 0), (L, W, 0), (L, W, H), (0, W, H))  # north, faces -y
    wall_with_opening(geo, "walls_plaster", 0.0, "y", (0, L), (0, H), (3.0, 7.0), (0.9, 2.4), facing=+1,
                      hole_material="window_glass")
    # Rug and curtains.
    geo.box("rug", (2.5, 2.0, LIFT), (7.5, 5.0, LIFT + 0.012))
    geo.box("curtains", (2.6, 0.10, 0.3), (3.0, 0.16, 2.8))
    geo.box("curtains", (7.0, 0.10, 0.3), (7.4, 0.16, 2.8))

    def table(x0, y0, w, d, h, legs_mat="table_wood"):
        geo.box("table_wood", (x0, y0, h - 0.04), (x0 + w, y0 + d, h))
        for lx, ly in [(x0 + 0.08, y0 + 0.08), (x0 + w - 0.08, y0 + 0.08), (x0 + 0.08, y0 + d - 0.08),
                       (x0 + w - 0.08, y0 + d - 0.08)]:
            geo.cylinder(legs_mat, (lx, ly, LIFT), 0.03, h - 0.04 - LIFT, segments=24)

    def chair(x, y, facing):
        s = 0.44
        geo.box("chair_wood", (x - s / 2, y - s / 2, 0.43), (x + s / 2, y + s / 2, 0.46))
        by = y + facing * (s / 2 - 0.02)
        geo.box("chair_wood", (x - s / 2, min(by, by - facing * 0.03), 0.46),
                (x + s / 2, max(by, by - facing * 0.03), 0.9))
        for dx in (-s / 2 + 0.03, s / 2 - 0.03):
            for dy in (-s / 2 + 0.03, s / 2 - 0.03):
                geo.cylinder("chair_wood", (x + dx, y + dy, LIFT), 0.018, 0.43 - LIFT, segments=12)

    # Dining table with six chairs, a desk with one chair.
    table(3.5, 2.8, 2.4, 1.0, 0.75)
    for cx in (4.0, 4.7, 5.4):
        chair(cx, 2.45, -1)
        chair(cx, 4.15, +1)
    table(8.2, 0.6, 1.4, 0.7, 0.74)
    chair(8.9, 1.6, +1)

    # Two bookcases against the north wall, full of books.
    for x0 in (0.6, 2.0):
        x1, y0, y1, top = x0 + 1.2, W - 0.38, W - 0.02, 2.2
        geo.box("shelf_wood", (x0, y0, LIFT), (x0 + 0.02, y1, top))
        geo.box("shelf_wood", (x1 - 0.02, y0, LIFT), (x1, y1, top))
        geo.box("shelf_wood", (x0 + 0.02, y1 - 0.01, LIFT), (x1 - 0.02, y1, top))
        for k in range(6):
            z = LIFT + 0.02 + k * 0.42
            geo.box("shelf_wood", (x0 + 0.02, y0, z), (x1 - 0.02, y1 - 0.01, z + 0.02))
            if k < 5:
                bx = x0 + 0.03
                i = 0
                while bx < x1 - 0.08:
                    bw = 0.025 + 0.015 * ((i * 7 + k * 3) % 4)
                    bh = 0.22 + 0.03 * ((i * 5 + k) % 5)
                    geo.box("books", (bx, y0 + 0.04, z + 0.021), (bx + bw, y1 - 0.03, z + 0.02 + bh))
                    bx += bw + 0.003
                    i += 1

    # Sofa by the east wall, with cushions.
    sx0, sy0 = L - 1.1, 2.0
    geo.box("sofa_fabric", (sx0, sy0, LIFT), (sx0 + 0.95, sy0 + 2.2, 0.42))
    geo.box("sofa_fabric", (sx0 + 0.75, sy0, 0.42), (sx0 + 0.95, sy0 + 2.2, 0.85))
    geo.box("sofa_fabric", (sx0, sy0 - 0.2, LIFT), (sx0 + 0.95, sy0, 0.62))
    geo.box("sofa_fabric", (sx0, sy0 + 2.2, LIFT), (sx0 + 0.95, sy0 + 2.4, 0.62))
    for k in range(3):
        geo.box("sofa_fabric", (sx0 + 0.05, sy0 + 0.05 + k * 0.72, 0.421), (sx0 + 0.72, sy0 + 0.7 + k * 0.72, 0.52))
    # Coffee table and a round side table.
    table(7.4, 2.6, 0.9, 0.6, 0.42)
    geo.cylinder("table_wood", (8.1, 5.2, LIFT), 0.3, 0.6, segments=96)

    # Floor lamps (metal pole, glass globe) and pendant globes.
    for (x, y) in [(0.5, 0.5), (9.5, 0.5), (9.5, 6.5), (0.5, 3.5)]:
        geo.cylinder("lamp_metal", (x, y, LIFT), 0.15, 0.03, segments=48)
        geo.cylinder("lamp_metal", (x, y, LIFT + 0.03), 0.015, 1.45, segments=24)
        geo.sphere("lamp_glass", (x, y, 1.7), 0.2, stacks=24, slices=44)
    for (x, y) in [(4.7, 3.3), (3.0, 1.5), (6.5, 1.5)]:
        geo.cylinder("lamp_metal", (x, y, 2.6), 0.006, H - 2.6 - 0.002, segments=8)
        geo.sphere("lamp_glass", (x, y, 2.4), 0.18, stacks=24, slices=44)
    # A plant pot with a spherical crown near the window.
    geo.cylinder("pot_ceramic", (1.2, 1.0, LIFT), 0.22, 0.45, segments=64)
    geo.sphere("plant", (1.2, 1.0, 0.95), 0.45, stacks=24, slices=48)

    g = Gltf()
    colors = {"walls_plaster": (0.9, 0.88, 0.82), "floor_parquet": (0.6, 0.4, 0.2), "rug": (0.5, 0.1, 0.1)}
    g.scene([g.node(name="furnished_room", mesh=geo.to_gltf(g, "furnished_room", colors))])
    g.write_glb(os.path.join(out, "furnished_room.glb"))
    write_map(out, {"floor_parquet": "wood_floor", "ceiling_tiles": "acoustic_ceiling_tile",
                    "walls_plaster": "plaster", "window_glass": "glass_window", "rug": "carpet_thick",
                    "curtains": "curtain_heavy", "table_wood": "wood_panel", "chair_wood": "chairs_wooden",
                    "shelf_wood": "wood_panel", "books": "wood_panel", "sofa_fabric": "seats_upholstered",
                    "lamp_metal": "metal", "lamp_glass": "glass_heavy", "pot_ceramic": "ceramic_tile",
                    "plant": "foam"})
    return geo.triangle_count()


def two_rooms(out):
    """Rooms A [0,6] and B [6.2,12.2] (x) by [0,5] by [0,3] separated by a
    20 cm partition with a 1 x 2.1 m doorway at y in [2, 3]; the door is its
    own node and mesh "door", hinged at (6.1, 2.0): rotate the node about z to
    open it. Written twice: two_rooms.gltf with the door closed in the
    doorway, two_rooms_door_open.gltf with it open into room B (otherwise the
    same bytes: same meshes, same buffer)."""
    L, W, H = 12.2, 5.0, 3.0
    xa, xb = 6.0, 6.2
    hole_y, hole_z = (2.0, 3.0), (0.0, 2.1)
    geo = Geometry()
    geo.quad("floor_a", (0, 0, 0), (xa, 0, 0), (xa, W, 0), (0, W, 0))
    geo.quad("floor_partition", (xa, 0, 0), (xb, 0, 0), (xb, W, 0), (xa, W, 0))
    geo.quad("floor_b", (xb, 0, 0), (L, 0, 0), (L, W, 0), (xb, W, 0))
    geo.quad("ceiling", (0, 0, H), (0, W, H), (L, W, H), (L, 0, H))
    geo.quad("walls", (0, 0, 0), (0, W, 0), (0, W, H), (0, 0, H))
    geo.quad("walls", (L, 0, 0), (L, 0, H), (L, W, H), (L, W, 0))
    geo.quad("walls", (0, 0, 0), (0, 0, H), (L, 0, H), (L, 0, 0))
    geo.quad("walls", (0, W, 0), (L, W, 0), (L, W, H), (0, W, H))
    # Partition: faces towards A (-x) and B (+x), and the doorway's reveal.
    wall_with_opening(geo, "partition", xa, "x", (0, W), (0, H), hole_y, hole_z, facing=-1)
    wall_with_opening(geo, "partition", xb, "x", (0, W), (0, H), hole_y, hole_z, facing=+1)
    y0, y1, zt = hole_y[0], hole_y[1], hole_z[1]
    geo.quad("partition", (xa, y0, 0), (xa, y0, zt), (xb, y0, zt), (xb, y0, 0))  # jamb, faces +y
    geo.quad("partition", (xa, y1, 0), (xb, y1, 0), (xb, y1, zt), (xa, y1, zt))  # jamb, faces -y
    geo.quad("partition", (xa, y0, zt), (xa, y1, zt), (xb, y1, zt), (xb, y0, zt))  # head, faces -z

    door_geo = Geometry()
    # Local frame: hinge at the origin, door along +y, 4 cm thick, 5 mm gaps.
    gap, half = 0.005, 0.02
    door_geo.box("door", (-half, gap, gap), (half, (y1 - y0) - gap, zt - gap))

    def write(filename, door_transform):
        g = Gltf()
        room = geo.to_gltf(g, "rooms")
        door = door_geo.to_gltf(g, "door")
        g.scene([g.node(name="rooms", mesh=room), g.node(name="door", mesh=door, **door_transform)])
        g.write_gltf(os.path.join(out, filename))

    write("two_rooms.gltf", {"translation": [(xa + xb) / 2, y0, 0.0]})
    # Open: turned -90 degrees about z, so the door runs from the hinge along +x
    # into room B, perpendicular to the partition. A 4 cm door turned about
    # (6.1, 2.0) itself would straddle the jamb (the face y = 2, x in [6, 6.2]),
    # so the hinge moves half the door's thickness plus its 5 mm gap into the
    # doorway: the open door occupies x in [6.105, 7.095], y in [2.005, 2.045],
    # z in [0.005, 2.095], touching nothing, and leaves y in [2.05, 3] clear.
    s = math.sqrt(0.5)
    write("two_rooms_door_open.gltf",
          {"translation": [(xa + xb) / 2, y0 + half + gap, 0.0], "rotation": [0.0, 0.0, -s, s]})
    write_map(out, {"floor_a": "wood_floor", "floor_b": "carpet_thick", "floor_partition": "wood_floor",
                    "ceiling": "gypsum_board", "walls": "plaster", "partition": "gypsum_board", "door": "door_wood"})
    return geo.triangle_count() + door_geo.triangle_count()


def hall(out):
    """A 30 x 20 x 12 m hall: stage at the west end, raked audience blocks
    with an aisle, a rear balcony, side-wall wood panelling."""
    L, W, H = 30.0, 20.0, 12.0
    geo = Geometry()
    geo.quad("floor", (0, 0, 0), (L, 0, 0), (L, W, 0), (0, W, 0))
    geo.quad("ceiling", (0, 0, H), (0, W, H), (L, W, H), (L, 0, H))
    geo.quad("stage_wall", (0, 0, 0), (0, W, 0), (0, W, H), (0, 0, H))
    geo.quad("rear_wall", (L, 0, 0), (L, 0, H), (L, W, H), (L, W, 0))
    # Side walls: panelled below 4 m, plaster above (split at z = 4 on shared edges).
    for y, sign in ((0.0, +1), (W, -1)):
        for mat, z0, z1 in (("side_panels", 0, 4), ("side_plaster", 4, H)):
            a, b, c, d = (0, y, z0), (0, y, z1), (L, y, z1), (L, y, z0)
            if sign > 0:
                geo.quad(mat, a, b, c, d)
            else:
                geo.quad(mat, a, d, c, b)
    geo.box("stage", (LIFT, LIFT, LIFT), (8.0, W - LIFT, 1.0))
    # Raked audience: 18 rows, two blocks with a centre aisle.
    for r in range(18):
        x0 = 10.0 + r * 1.0
        top = 0.45 + r * 0.15
        for y0, y1 in ((1.5, 9.2), (10.8, 18.5)):
            geo.box("audience", (x0, y0, LIFT), (x0 + 0.95, y1, top))
    # Rear balcony with audience on it.
    geo.box("balcony", (26.0, LIFT, 5.0), (L - LIFT, W - LIFT, 5.4))
    for r in range(3):
        geo.box("audience", (26.2 + r * 1.2, 1.0, 5.4 + LIFT), (27.3 + r * 1.2, W - 1.0, 5.85 + r * 0.3))
    # Ceiling reflectors over the stage.
    for k in range(4):
        geo.box("reflectors", (1.0 + k * 2.0, 4.0, 8.0 + 0.3 * k), (2.8 + k * 2.0, 16.0, 8.08 + 0.3 * k))
    g = Gltf()
    g.scene([g.node(name="hall", mesh=geo.to_gltf(g, "hall"))])
    g.write_glb(os.path.join(out, "hall.glb"))
    write_map(out, {"floor": "wood_floor", "ceiling": "plaster", "stage_wall": "wood_panel", "rear_wall": "fabric_panel",
                    "side_panels": "wood_panel", "side_plaster": "plaster", "stage": "stage_floor",
                    "audience": "audience", "balcony": "concrete", "reflectors": "wood_panel"})
    return geo.triangle_count()


def outdoor(out):
    """Ground 100 x 100 m (grass, facing up) and one brick wall 10 x 0.3 x 3 m."""
    geo = Geometry()
    geo.quad("ground", (-50, -50, 0), (50, -50, 0), (50, 50, 0), (-50, 50, 0))
    geo.box("wall", (-5.0, 4.85, LIFT), (5.0, 5.15, 3.0))
    g = Gltf()
    g.scene([g.node(name="outdoor", mesh=geo.to_gltf(g, "outdoor"))])
    g.write_gltf(os.path.join(out, "outdoor.gltf"))
    write_map(out, {"ground": "grass", "wall": "brick"})
    return geo.triangle_count()


def main():
    here = os.path.dirname(os.path.abspath(__file__))
    root = sys.argv[1] if len(sys.argv) > 1 else os.path.join(here, "..", "samples")
    for name, fn in [("shoebox", shoebox), ("furnished_room", furnished_room), ("two_rooms", two_rooms),
                     ("hall", hall), ("outdoor", outdoor)]:
        d = os.path.join(root, name)
        os.makedirs(d, exist_ok=True)
        n = fn(d)
        print(f"{name}: {n} triangles")


if __name__ == "__main__":
    main()
