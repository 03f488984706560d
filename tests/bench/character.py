"""A skinned character walking across a still room, and two other shapes of the same
problem: rigid parts that move part of the time and pause between moves, and a mesh that
morphs by an animated weight. The deforming shots `exact` and `auto` are measured on
(tests/bench/character_cost.py).

    python tests/bench/character.py walk.glb [--triangles 50000] [--frames 48] [--speed 0.5]
                                             [--variant skinned|rigid|morphed]

The character: 22 joints (root, hips, spine, chest, neck, head, and per side a shoulder,
upper arm, forearm, hand, thigh, shin, foot and toes), its body capsules along the bones
with weights blended over a few centimetres either side of each joint. A walk cycle of one
second: the feet are placed by inverse kinematics, so the foot in stance holds still on the
floor, the arms swing opposite the legs, the torso bobs and twists, the head nods and holds;
neck, shoulders and hands hold still all along. The room (floor, back wall, side wall, a
crate), the camera and the point light casting the shadow do not move. Keys are in seconds,
one a frame at 24 frames per second; the same arguments write the same bytes.
"""
import argparse
import math
import pathlib
import sys

sys.path.insert(0, str(pathlib.Path(__file__).resolve().parent.parent / "gltf"))
from make_gltf import (TRIANGLE_STRIP, Gltf, axis_angle, blob_targets, cube, smooth_normals,  # noqa: E402
                       translation_matrix, uv_sphere)

FPS = 24
CYCLE_SECONDS = 1.0  # two steps
STANCE = 0.6  # the share of a cycle a foot is on the floor
THIGH, SHIN = 0.42, 0.42
ANKLE_HEIGHT, LIFT = 0.08, 0.07
HIPS_HEIGHT, HIPS_DROP, BOB = 0.95, 0.03, 0.015  # the hips walk a little lower than they stand

SKIN, SHIRT, TROUSERS, SHOES = (0.85, 0.6, 0.45), (0.2, 0.35, 0.7), (0.25, 0.25, 0.3), (0.1, 0.08, 0.06)


def skeleton():
    """(name, parent, bind position in the world), parents first. The character faces +x, y
    up; its left side is toward -z."""
    joints = [("root", None, (0, 0, 0)), ("hips", "root", (0, HIPS_HEIGHT, 0)),
              ("spine", "hips", (0, 1.10, 0)), ("chest", "spine", (0, 1.30, 0)),
              ("neck", "chest", (0, 1.50, 0)), ("head", "neck", (0, 1.60, 0))]
    for side, z in (("left", -1), ("right", 1)):
        joints += [(f"{side}_shoulder", "chest", (0, 1.42, 0.06 * z)),
                   (f"{side}_upper_arm", f"{side}_shoulder", (0, 1.42, 0.20 * z)),
                   (f"{side}_forearm", f"{side}_upper_arm", (0, 1.13, 0.22 * z)),
                   (f"{side}_hand", f"{side}_forearm", (0, 0.86, 0.23 * z)),
                   (f"{side}_thigh", "hips", (0, ANKLE_HEIGHT + SHIN + THIGH, 0.1 * z)),
                   (f"{side}_shin", f"{side}_thigh", (0, ANKLE_HEIGHT + SHIN, 0.1 * z)),
                   (f"{side}_foot", f"{side}_shin", (0, ANKLE_HEIGHT, 0.1 * z)),
                   (f"{side}_toes", f"{side}_foot", (0.14, 0.03, 0.1 * z))]
    return joints


def body_chains():
    """The body as capsules along polylines: (points, the joint each segment is bound to,
    radius profile [(metres along, radius)], cross-section scale (front-back or up-down,
    across), colours [(below this height, colour)])."""
    torso = ([(0, 0.80, 0), (0, 0.95, 0), (0, 1.10, 0), (0, 1.30, 0), (0, 1.50, 0), (0, 1.60, 0), (0, 1.86, 0)],
             ["hips", "hips", "spine", "chest", "neck", "head"],
             [(0, 0.14), (0.15, 0.16), (0.25, 0.13), (0.5, 0.17), (0.64, 0.15), (0.7, 0.05), (0.78, 0.05),
              (0.84, 0.09), (0.93, 0.105), (1.06, 0.08)], (0.7, 1.0),
             [(0.93, TROUSERS), (1.49, SHIRT), (9, SKIN)])
    chains = [torso]
    for side, z in (("left", -1), ("right", 1)):
        chains.append(([(0, 1.47, 0.2 * z), (0, 1.42, 0.2 * z), (0, 1.13, 0.22 * z), (0, 0.86, 0.23 * z),
                        (0, 0.70, 0.23 * z)],
                       [f"{side}_shoulder", f"{side}_upper_arm", f"{side}_forearm", f"{side}_hand"],
                       [(0, 0.055), (0.1, 0.05), (0.34, 0.04), (0.6, 0.032), (0.68, 0.045), (0.77, 0.04)],
                       (0.8, 1.0), [(1.25, SKIN), (9, SHIRT)]))
        chains.append(([(0, 0.98, 0.1 * z), (0, 0.92, 0.1 * z), (0, 0.50, 0.1 * z), (0, 0.08, 0.1 * z),
                        (0, 0.03, 0.1 * z)],
                       ["hips", f"{side}_thigh", f"{side}_shin", f"{side}_foot"],
                       [(0, 0.085), (0.1, 0.08), (0.45, 0.055), (0.6, 0.05), (0.85, 0.035), (0.95, 0.04)],
                       (1.0, 1.0), [(0.1, SHOES), (9, TROUSERS)]))
        chains.append(([(-0.06, 0.05, 0.1 * z), (0.0, 0.045, 0.1 * z), (0.14, 0.035, 0.1 * z),
                        (0.22, 0.035, 0.1 * z)],
                       [f"{side}_foot", f"{side}_foot", f"{side}_toes"],
                       [(0, 0.045), (0.1, 0.05), (0.28, 0.045)], (0.55, 1.0), [(9, SHOES)]))
    return chains


def smoothstep(t):
    t = min(1.0, max(0.0, t))
    return t * t * (3 - 2 * t)


def normalized(v):
    length = math.sqrt(sum(c * c for c in v))
    return [c / length for c in v]


def cross(a, b):
    return [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]


def profile_radius(profile, s, length):
    """The profile eased between its points, rounded off like a capsule at both ends."""
    radius = profile[-1][1]
    for (s0, r0), (s1, r1) in zip(profile, profile[1:]):
        if s <= s1:
            radius = r0 + (r1 - r0) * smoothstep((s - s0) / (s1 - s0))
            break
    end, rounding = min(s, length - s), max(profile[0][1], profile[-1][1])
    if end < rounding:
        radius *= math.sqrt(max(0.0, 1 - (1 - end / rounding) ** 2))
    return radius


def bone_weights(starts, bones, s, blend=0.04):
    """{joint: weight} at s metres along a chain whose segments start at `starts` and are
    bound to `bones`: the segment's joint, eased into its neighbour's over `blend` metres
    either side of the joint between them."""
    b = max(i for i, start in enumerate(starts[:-1]) if start <= s)
    weights = {bones[b]: 1.0}
    for boundary, neighbour in ((b, b - 1), (b + 1, b + 1)):
        if 0 < boundary < len(bones) and 0 <= neighbour < len(bones):
            reach = min(blend, (starts[boundary] - starts[boundary - 1]) / 2,
                        (starts[boundary + 1] - starts[boundary]) / 2)
            share = 1 - smoothstep(0.5 + abs(s - starts[boundary]) / (2 * reach))
            if share > 0:
                weights[bones[b]] -= share
                weights[bones[neighbour]] = weights.get(bones[neighbour], 0.0) + share
    return weights


def capsule(chain, sides, rings, joint_index, out):
    """Appends one chain's rings to `out` (positions, joints, weights, colors, indices)."""
    points, bones, profile, (scale_n, scale_b), colours = chain
    starts = [0.0]
    for a, b in zip(points, points[1:]):
        starts.append(starts[-1] + math.dist(a, b))
    length = starts[-1]
    first = len(out["positions"]) // 3
    for ring in range(rings + 1):
        s = length * ring / rings
        b = max(i for i, start in enumerate(starts[:-1]) if start <= s)
        along = (s - starts[b]) / (starts[b + 1] - starts[b])
        centre = [p + (q - p) * along for p, q in zip(points[b], points[b + 1])]
        tangent = normalized([q - p for p, q in zip(points[b], points[b + 1])])
        reference = [0, 1, 0] if abs(tangent[0]) > 0.7 else [1, 0, 0]
        n = normalized([r - sum(x * y for x, y in zip(reference, tangent)) * t for r, t in zip(reference, tangent)])
        binormal = cross(tangent, n)
        radius = profile_radius(profile, s, length)
        weights = sorted(bone_weights(starts, bones, s).items(), key=lambda item: -item[1])
        joints = [joint_index[name] for name, _ in weights] + [0] * (4 - len(weights))
        colour = next(c for below, c in colours if centre[1] < below)
        for side in range(sides):
            angle = 2 * math.pi * side / sides
            u, v = radius * scale_n * math.cos(angle), radius * scale_b * math.sin(angle)
            out["positions"] += [centre[k] + u * n[k] + v * binormal[k] for k in range(3)]
            out["joints"] += joints
            out["weights"] += [w for _, w in weights] + [0.0] * (4 - len(weights))
            out["colors"] += [*colour, 1.0]
    for ring in range(rings):
        for side in range(sides):
            a, b = first + ring * sides + side, first + ring * sides + (side + 1) % sides
            out["indices"] += [a, b, b + sides, a, b + sides, a + sides]


def body_mesh(triangles, joint_index):
    """The body's vertices and triangles: at least `triangles`, spread over the chains by length."""
    chains = body_chains()
    sides = max(8, round(math.sqrt(triangles / 6)))
    lengths = [sum(math.dist(a, b) for a, b in zip(chain[0], chain[0][1:])) for chain in chains]
    rings_needed = math.ceil(triangles / (2 * sides))
    out = {"positions": [], "joints": [], "weights": [], "colors": [], "indices": []}
    for chain, length in zip(chains, lengths):
        capsule(chain, sides, max(4, math.ceil(rings_needed * length / sum(lengths))), joint_index, out)
    out["normals"] = smooth_normals(out["positions"], out["indices"])
    return out


def foot_target(t, phase, speed, start_x):
    """Where a foot's ankle is at t (x, height) and its pitch and its toes' bend (degrees):
    planted where the hips pass over it half way through its stance, then swung to the next
    plant one stride on."""
    stride = speed * CYCLE_SECONDS
    cycle = t / CYCLE_SECONDS + phase
    k = math.floor(cycle)
    c = cycle - k
    plant = start_x + stride * (k + STANCE / 2 - phase)
    if c < STANCE:
        return plant, ANKLE_HEIGHT, 0.0, 0.0
    w = (c - STANCE) / (1 - STANCE)
    lift = math.sin(math.pi * w)
    return plant + stride * smoothstep(w), ANKLE_HEIGHT + LIFT * lift, 12 * lift, 15 * lift


def leg_angles(dx, dy):
    """Thigh and knee bends (degrees about z) that put the ankle at (dx, dy) from the hip,
    the knee forward; out of reach, the leg points straight at it."""
    d = min(max(math.hypot(dx, dy), 0.1), THIGH + SHIN - 1e-9)
    toward = math.atan2(dx, -dy)
    at_hip = math.acos((THIGH ** 2 + d ** 2 - SHIN ** 2) / (2 * THIGH * d))
    at_knee = math.acos((THIGH ** 2 + SHIN ** 2 - d ** 2) / (2 * THIGH * SHIN))
    return math.degrees(toward + at_hip), -math.degrees(math.pi - at_knee)


def pose(t, speed, start_x):
    """{joint: ("translation", xyz) or ("rotation", degrees about its axis)} at time t."""
    c = t / CYCLE_SECONDS
    hips_y = HIPS_HEIGHT - HIPS_DROP - BOB * math.cos(4 * math.pi * (c - 0.05))  # lowest in double support
    root_x = start_x + speed * t
    hip_joint_y = hips_y + (ANKLE_HEIGHT + SHIN + THIGH - HIPS_HEIGHT)
    out = {"root": [root_x, 0, 0], "hips": [0, hips_y, 0],
           "spine": 4 * math.sin(2 * math.pi * c), "chest": -6 * math.sin(2 * math.pi * c),
           # A nod clipped flat: the head holds still a few frames at each end of it.
           "head": 2 * max(-1.0, min(1.0, 1.6 * math.sin(4 * math.pi * c)))}
    for side, phase in (("left", 0.0), ("right", 0.5)):
        x, y, pitch, toes = foot_target(t, phase, speed, start_x)
        thigh, knee = leg_angles(x - root_x, y - hip_joint_y)
        out.update({f"{side}_thigh": thigh, f"{side}_shin": knee, f"{side}_foot": pitch - thigh - knee,
                    f"{side}_toes": toes, f"{side}_upper_arm": -0.7 * thigh,
                    f"{side}_forearm": 8 + 0.6 * max(0.0, -0.7 * thigh)})
    return out


SPINE_AXIS = {"spine": [0, 1, 0], "chest": [0, 1, 0]}  # twists; every other joint bends about z


def animate_walk(g, nodes, frames, speed):
    times = [f / FPS for f in range(frames)]
    start_x = -speed * times[-1] / 2  # the walk is centred in the room
    poses = [pose(t, speed, start_x) for t in times]
    for name in poses[0]:
        if name in ("root", "hips"):
            g.animate(nodes[name], "translation", times, [v for p in poses for v in p[name]])
        else:
            axis = SPINE_AXIS.get(name, [0, 0, 1])
            g.animate(nodes[name], "rotation", times, [q for p in poses for q in axis_angle(axis, p[name])])


def room(g):
    """The still set: floor, back wall, side wall, a crate; camera and point light."""
    floor = g.material("floor", (0.6, 0.58, 0.55), roughness=0.9)
    wall = g.material("wall", (0.75, 0.75, 0.7), roughness=0.9)
    wood = g.material("crate", (0.55, 0.4, 0.25), roughness=0.7)
    g.node(name="floor", mesh=g.mesh([{"positions": [-4, 0, -2, -4, 0, 4.5, 4, 0, -2, 4, 0, 4.5],
                                       "mode": TRIANGLE_STRIP, "material": floor}]))
    g.node(name="back_wall", mesh=g.mesh([{"positions": [-4, 0, -2, 4, 0, -2, 4, 3.5, -2, -4, 3.5, -2],
                                           "indices": [0, 1, 2, 0, 2, 3], "material": wall}]))
    g.node(name="side_wall", mesh=g.mesh([{"positions": [-3, 0, 4.5, -3, 0, -2, -3, 3.5, -2, -3, 3.5, 4.5],
                                           "indices": [0, 1, 2, 0, 2, 3], "material": wall}]))
    positions, indices = cube(0.3)
    g.node(name="crate", mesh=g.mesh([{"positions": positions, "indices": indices, "material": wood}]),
           translation=[1.4, 0.3, -1.2], rotation=axis_angle([0, 1, 0], 20))
    g.node(name="eye", camera=g.camera(0.75, name="main"), translation=[0.6, 0.95, 2.9],
           rotation=axis_angle([0, 1, 0], 12))
    g.node(name="bulb", light=g.light("point", 5000.0, (1.0, 0.95, 0.9)), translation=[-1.2, 3.0, 2.0])


def skinned_character(triangles=50000, frames=48, speed=0.5):
    """The character walking at `speed` metres a second for `frames` frames."""
    g = Gltf()
    room(g)
    joints = skeleton()
    nodes, where = {}, {}
    for name, parent, position in joints:
        offset = [p - q for p, q in zip(position, where[parent])] if parent else list(position)
        nodes[name], where[name] = g.node(nodes.get(parent), name=name, translation=offset), position
    skin = g.skin([nodes[name] for name, _, _ in joints],
                  [translation_matrix(*(-c for c in where[name])) for name, _, _ in joints])
    body = body_mesh(triangles, {name: i for i, (name, _, _) in enumerate(joints)})
    clothes = g.material("clothes", (1.0, 1.0, 1.0), roughness=0.6)  # painted by the vertex colours
    # The skinned mesh's node is a root without a transform of its own (glTF ignores it).
    g.node(name="character", mesh=g.mesh([dict(body, material=clothes)], name="character"), skin=skin)
    animate_walk(g, nodes, frames, speed)
    return g


MOVE = 0.15  # the share of the shot one move of a rigid part or of the morph lasts


def moves_with_pauses(duration, first, move, pause):
    """[(start, end)] of moves lasting `move` from `first` on, `pause` apart, all within
    `duration`; first, move and pause are shares of the duration (a shot of any length
    moves and pauses alike)."""
    moves, start = [], first
    while start + move <= 1:
        moves.append((start * duration, (start + move) * duration))
        start += move + pause
    return moves


def held_keys(duration, moves, value_at):
    """Times and values of a channel that holds value_at(k) after its k-th move (k = 0 before any)."""
    times, values = [0.0], [value_at(0)]
    for k, (start, end) in enumerate(moves, 1):
        times += [start, end]
        values += [value_at(k - 1), value_at(k)]
    if times[-1] < duration:
        times.append(duration)
        values.append(value_at(len(moves)))
    return times, [v for value in values for v in value]


def rigid_parts(triangles=50000, frames=48, speed=0.5):
    """Four smooth rigid parts (ellipsoids of a quarter of the triangles each) where the
    character walks: each moves (slides `speed` metres a second and turns) part of the time
    and pauses between moves, the parts out of step."""
    g = Gltf()
    room(g)
    duration = (frames - 1) / FPS
    step = speed * MOVE * duration  # a move's slide
    rings = max(2, math.ceil(math.sqrt(triangles / 16)))  # 2 * rings * 2 rings: a quarter of the triangles
    positions, normals, _, indices = uv_sphere(1.0, rings, 2 * rings)
    paint = g.material("paint", (0.2, 0.35, 0.7), roughness=0.5)
    mesh = g.mesh([{"positions": positions, "normals": normals, "indices": indices, "material": paint}], name="part")
    for i in range(4):
        x, y = -0.9 + 0.6 * i, 0.25 + 0.3 * (i % 2)
        node = g.node(name=f"part{i}", mesh=mesh, translation=[x, y, 0], scale=[0.25, 0.2 + 0.05 * i, 0.18])
        moves = moves_with_pauses(duration, 0.05 + 0.05 * i, MOVE, 0.1 + 0.05 * i)
        g.animate(node, "translation", *held_keys(duration, moves, lambda k: [x + step * k, y, 0]))
        g.animate(node, "rotation", *held_keys(duration, moves, lambda k: axis_angle([0, 1, 0], 30 * k)))
    return g


def morphing_shape(triangles=50000, frames=48, speed=0.5):
    """A sphere of `triangles` with two morph targets (tall, bumpy) whose weights change and
    hold in turn; it slides `speed` metres a second while it morphs."""
    g = Gltf()
    room(g)
    duration = (frames - 1) / FPS
    step = speed * MOVE * duration
    segments = max(4, round(math.sqrt(triangles)))
    positions, _, _, indices = uv_sphere(0.45, max(2, math.ceil(triangles / (2 * segments))), segments)
    normals, targets = blob_targets(positions, indices)
    clay = g.material("clay", (0.3, 0.5, 0.8), roughness=0.4)
    node = g.node(name="shape", translation=[0, 0.9, 0], mesh=g.mesh(
        [{"positions": positions, "normals": normals, "indices": indices, "material": clay, "targets": targets}],
        name="shape", weights=[0, 0]))
    moves = moves_with_pauses(duration, 0.08, MOVE, 0.12)
    shapes = [[0, 0], [1, 0], [0.4, 1], [0, 0.6]]
    g.animate(node, "weights", *held_keys(duration, moves, lambda k: shapes[k % len(shapes)]))
    g.animate(node, "translation", *held_keys(duration, moves, lambda k: [step * (k - len(moves) / 2), 0.9, 0]))
    return g


VARIANTS = {"skinned": skinned_character, "rigid": rigid_parts, "morphed": morphing_shape}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("out", help="the file to write: .glb or .gltf")
    parser.add_argument("--variant", choices=sorted(VARIANTS), default="skinned")
    parser.add_argument("--triangles", type=int, default=50000, help="at least this many on what moves")
    parser.add_argument("--frames", type=int, default=48, help="animation length in frames at 24 per second (2+)")
    parser.add_argument("--speed", type=float, default=0.5, help="walk speed, metres a second")
    args = parser.parse_args()
    if args.frames < 2:
        parser.error("--frames must be 2 or more")
    print(VARIANTS[args.variant](args.triangles, args.frames, args.speed).write(args.out))


if __name__ == "__main__":
    main()
