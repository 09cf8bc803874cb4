"""One procedural house: floor plan, structure and furniture assembled into a scene and its annotation."""

from __future__ import annotations

import numpy as np
import trimesh

from navbench.scene.annotations import ObjectAnnotation, RoomAnnotation
from navbench.scene.procedural.config import PLAN_UNIT, HouseConfig
from navbench.scene.procedural.furnish import assign_colours, furnish
from navbench.scene.procedural.furniture import COLOURS
from navbench.scene.procedural.plan import Room, floor_plan, room_types
from navbench.scene.procedural.structure import (
    CEILING_COLOUR,
    FLOOR_COLOURS,
    WALL_COLOURS,
    coloured_box,
    trim_mesh,
    wall_mesh,
)


def generate_house(seed: int, config: HouseConfig = HouseConfig()) -> tuple[trimesh.Scene, dict]:
    """Build house ``seed``: a scene (nodes ``floor_<room>``, ``walls``, ``ceiling``, ``obj_<id>``) + semantics."""
    cfg = config
    rng = np.random.default_rng(seed)
    rects_u, hallway, doors = floor_plan(rng, cfg)
    types = room_types(rng, rects_u, hallway)
    t, h = cfg.wall_thickness, cfg.wall_height

    rooms: list[Room] = []
    seen: dict[str, int] = {}
    for (x0, z0, x1, z1), rtype in zip(rects_u, types):
        seen[rtype] = seen.get(rtype, 0) + 1
        name = rtype if seen[rtype] == 1 else f"{rtype}_{seen[rtype]}"
        rect = (x0 * PLAN_UNIT, z0 * PLAN_UNIT, x1 * PLAN_UNIT, z1 * PLAN_UNIT)
        interior = (rect[0] + t / 2, rect[1] + t / 2, rect[2] - t / 2, rect[3] - t / 2)
        rooms.append(Room(name, rtype, rect, interior))

    wall_rgb = WALL_COLOURS[int(rng.integers(len(WALL_COLOURS)))]
    palette = rng.permutation(len(FLOOR_COLOURS))
    floor_rgb = [FLOOR_COLOURS[int(palette[i % len(palette)])] for i in range(len(rooms))]

    scene = trimesh.Scene()
    for room, rgb in zip(rooms, floor_rgb):
        x0, z0, x1, z1 = room.rect
        floor = coloured_box((x0, -0.1, z0), (x1, 0.0, z1), rgb)
        scene.add_geometry(floor, node_name=f"floor_{room.name}", geom_name=f"floor_{room.name}")
    trim_rgb = tuple(int(0.82 * c) for c in wall_rgb)
    walls = trimesh.util.concatenate([wall_mesh(rects_u, doors, cfg, wall_rgb),
                                      trim_mesh(rects_u, doors, cfg, trim_rgb)])
    scene.add_geometry(walls, node_name="walls", geom_name="walls")
    ceiling = trimesh.util.concatenate(
        [coloured_box((r.rect[0], h, r.rect[1]), (r.rect[2], h + 0.1, r.rect[3]), CEILING_COLOUR) for r in rooms])
    scene.add_geometry(ceiling, node_name="ceiling", geom_name="ceiling")

    items = furnish(rng, cfg, rooms, doors) if cfg.furnish else []
    assign_colours(rng, items, floor_rgb, wall_rgb)
    objects = []
    for obj_id, p in enumerate(items, start=1):
        mesh = p.world_mesh()
        scene.add_geometry(mesh, node_name=f"obj_{obj_id}", geom_name=f"obj_{obj_id}")
        lo, hi = mesh.bounds
        objects.append(ObjectAnnotation(
            id=obj_id, category=p.category, room=rooms[p.room].name, colour=p.colour,
            colour_rgb=COLOURS[p.colour], aabb_min=tuple(float(v) for v in lo), aabb_max=tuple(float(v) for v in hi),
        ).to_json())

    room_json = []
    for r in rooms:
        x0, z0, x1, z1 = r.interior
        ann = RoomAnnotation(r.name, (round(x0, 5), 0.0, round(z0, 5)), (round(x1, 5), h, round(z1, 5)))
        room_json.append({**ann.to_json(), "type": r.type})
    door_json = [
        {
            "rooms": [rooms[d.rooms[0]].name, rooms[d.rooms[1]].name],
            "center": [round(d.coord * PLAN_UNIT, 5), 0.0, round((d.lo + d.hi) / 2 * PLAN_UNIT, 5)] if d.axis == "z"
            else [round((d.lo + d.hi) / 2 * PLAN_UNIT, 5), 0.0, round(d.coord * PLAN_UNIT, 5)],
            "width": round((d.hi - d.lo) * PLAN_UNIT, 5),
            "height": cfg.door_height,
            "wall_axis": d.axis,
        }
        for d in doors
    ]
    semantic = {"scene_id": f"house_seed{seed}", "seed": int(seed), "rooms": room_json, "objects": objects,
                "doors": door_json}
    return scene, semantic

