"""Independent check of a cleave MCAP recording with the PyPI `mcap` reader.

Every message must decode as JSON; /surface must carry schema foxglove.SceneUpdate with a
triangle list; /stats must have one message per step. With --expect-rest, the recorded surface
must fall, touch the ground (min z near 0) and come to rest (tiny kinetic energy at the end).
With --expect-cut, /events must hold `cut` events, the last frame must have at least
--min-pieces pieces, each piece's surface (its original and cut triangle lists, welded by
position) must be closed with every edge in exactly two triangles, and the run must end at rest
on the ground.

Optional checks, each independent of the above (they run first, so that their results show even
when a later check fails; each prints its own line and the run fails if any of them fails):
--max-pieces N: the last /surface frame must have at most N pieces (grouped as in --expect-cut).
--strict-closed: in the last frame, every piece's surface must be a closed manifold without
degenerate triangles as a reader of the f32 recording sees it: a piece's vertices are welded only
where their recorded coordinates are exactly equal (no tolerance), triangles whose welded corners
repeat or whose area is below 1e-14 m² count as zero-area triangles, and every undirected edge of
the remaining triangles must be in exactly two of them. The last frame is after all cuts, so an
edge in four triangles (two coinciding sheets of a cut that ends inside the material) is bad too.
Both counts are printed per failing piece and in total, and both must be 0.
--expect-rigid-at-end: the last /events `rigid` event (the runner's count of hand-offs, "... N rigid
now") leaves at least one rigid body: some pieces end the run on the rigid-body engine.
--expect-bounce H: between the first /events `impact` event (a static impact on a rigid fragment)
and the next one (or the end), the recorded surface's lowest point (/stats surface.min_z, the
height above the ground plane z = 0 of the scenes checked) rises at least H metres: the body
bounced off that impact.
--energy-after-last-cut PCT: E0 is /stats energy.total at the first step at or after the time of
the last /events `cut` event; at no later step may the total energy exceed E0 + PCT/100 * |E0|.
At the end, one line sums up what was checked.
"""
import json
import sys

from mcap.reader import make_reader


def main() -> int:
    path = sys.argv[1]
    expect_rest = "--expect-rest" in sys.argv
    expect_cut = "--expect-cut" in sys.argv
    expect_rigid = "--expect-rigid-at-end" in sys.argv
    last_rigid = None  # the message of the last `rigid` event
    min_pieces = int(sys.argv[sys.argv.index("--min-pieces") + 1]) if "--min-pieces" in sys.argv else 2
    max_pieces = int(sys.argv[sys.argv.index("--max-pieces") + 1]) if "--max-pieces" in sys.argv else None
    strict_closed = "--strict-closed" in sys.argv
    energy_pct = (float(sys.argv[sys.argv.index("--energy-after-last-cut") + 1])
                  if "--energy-after-last-cut" in sys.argv else None)
    bounce = float(sys.argv[sys.argv.index("--expect-bounce") + 1]) if "--expect-bounce" in sys.argv else None
    impact_times = []  # the times of the `impact` events
    counts = {}
    stats = []
    cuts = 0
    cut_times = []
    last_surface = None
    surfaces = []  # (time, frame) of the surface frames sampled for the closedness check
    with open(path, "rb") as f:
        reader = make_reader(f)
        for schema, channel, message in reader.iter_messages():
            data = json.loads(message.data)
            counts[channel.topic] = counts.get(channel.topic, 0) + 1
            if channel.topic == "/surface":
                assert schema.name == "foxglove.SceneUpdate", schema.name
                assert schema.encoding == "jsonschema", schema.encoding
                tri = data["entities"][0]["triangles"][0]
                assert len(tri["indices"]) % 3 == 0 and len(tri["points"]) > 0
                last_surface = data
                if len(surfaces) == 0 or message.log_time - surfaces[-1][0] >= 0.5e9:
                    surfaces.append((message.log_time, data))
            elif channel.topic == "/stats":
                stats.append(data)
            elif channel.topic == "/events" and data["kind"] == "impact":
                impact_times.append(data["time"])
            elif channel.topic == "/events" and data["kind"] == "rigid":
                last_rigid = data["message"]
            elif channel.topic == "/events" and data["kind"] in ("cut", "fracture"):
                cuts += 1
                cut_times.append(data["time"])
    print(f"{path}: {counts}")
    for topic in ("/surface", "/stats", "/events"):
        assert counts.get(topic, 0) > 0, f"no messages on {topic}"
    checked = ["JSON messages and topics"]
    failed = []
    if max_pieces is not None:
        name = f"--max-pieces {max_pieces}"
        checked.append(name)
        if not check_max_pieces(last_surface, max_pieces):
            failed.append(name)
    if strict_closed:
        name = "--strict-closed (last frame: exact weld, no zero-area triangles, every edge in two)"
        checked.append(name)
        if not check_strict_closed(last_surface):
            failed.append(name)
    if expect_rigid:
        name = "--expect-rigid-at-end (the last `rigid` event leaves a rigid body)"
        checked.append(name)
        rigid_now = int(last_rigid.split("; ")[-1].split(" ")[0]) if last_rigid else 0
        print(f"last rigid event: {last_rigid!r}")
        if rigid_now < 1:
            failed.append(name)
    if bounce is not None:
        name = f"--expect-bounce {bounce:g} (the lowest point rises after the first impact)"
        checked.append(name)
        first_impact = impact_times[0] if impact_times else None
        following = next((t for t in impact_times if first_impact is not None and t > first_impact), float("inf"))
        after = [s["surface"]["min_z"] for s in stats
                 if first_impact is not None and first_impact < s["time"] <= following]
        height = max(after) if after else float("nan")
        print(f"first impact at {first_impact} s, next at {following} s; highest lowest point between: {height:.4f} m")
        if not after or not height >= bounce:
            failed.append(name)
    if energy_pct is not None:
        name = f"--energy-after-last-cut {energy_pct:g} %"
        checked.append(name)
        if not check_energy_after_last_cut(stats, cut_times, energy_pct):
            failed.append(name)
    current = None  # the check under way, when one of the asserting checks below fails
    try:
        if expect_rest:
            current = "--expect-rest (falls, reaches the ground, rests)"
            checked.append(current)
            start_z = stats[0]["surface"]["min_z"]
            lowest = min(s["surface"]["min_z"] for s in stats)
            final = stats[-1]
            print(f"min z: start {start_z:.4f} m, lowest {lowest:.4f} m, final {final['surface']['min_z']:.4f} m; "
                  f"final kinetic energy {final['energy']['kinetic']:.3e} J")
            assert start_z > 0.2, "the bunny should start above the ground"
            assert abs(lowest) < 0.02, "the bunny should reach the ground"
            assert final["energy"]["kinetic"] < 1e-3, "the bunny should come to rest"
        if expect_cut:
            current = f"--expect-cut (cut events, at least {min_pieces} pieces, closed, separated, at rest)"
            checked.append(current)
            check_cut(last_surface, surfaces, cuts, stats, min_pieces)
        current = None
    finally:
        if current is not None:
            failed.append(current)
        print(f"checked: {'; '.join(checked)}: " + (f"FAILED: {'; '.join(failed)}" if failed else "all passed"))
    return 1 if failed else 0


def piece_lists(surface):
    """Groups the triangle lists into pieces: lists come in piece order, original before cut,
    colour tells the kind. Returns one dict per piece with its "lists"."""
    pieces = []
    current = None
    for lst in surface["entities"][0]["triangles"]:
        is_cut = lst["color"]["g"] < 0.5
        if current is None or not is_cut or current["has_cut"]:
            current = {"lists": [], "has_cut": False}
            pieces.append(current)
        current["lists"].append(lst)
        current["has_cut"] = current["has_cut"] or is_cut
    return pieces


def closed_pieces(surface, odd_only=False):
    """Groups the triangle lists into pieces (as piece_lists) and returns, per piece, (triangles,
    edges not in exactly two)."""
    pieces = piece_lists(surface)
    result = []
    tolerance = 1e-7  # metres: above f32 rounding of the recorded points (1.5e-8 at 0.2 m), far below an element
    for piece in pieces:
        cells = {}
        ids = []
        for lst in piece["lists"]:
            for p in lst["points"]:
                x = (p["x"], p["y"], p["z"])
                key = tuple(int(v // tolerance) for v in x)
                found = None
                for dx in (-1, 0, 1):
                    for dy in (-1, 0, 1):
                        for dz in (-1, 0, 1):
                            for (q, qid) in cells.get((key[0] + dx, key[1] + dy, key[2] + dz), ()):
                                if max(abs(a - b) for a, b in zip(x, q)) <= tolerance:
                                    found = qid
                if found is None:
                    found = len(ids)
                    cells.setdefault(key, []).append((x, found))
                ids.append(found)
        edges = {}
        triangles = 0
        offset = 0
        for lst in piece["lists"]:
            idx = lst["indices"]
            for t in range(0, len(idx), 3):
                a, b, c = (ids[offset + idx[t]], ids[offset + idx[t + 1]], ids[offset + idx[t + 2]])
                triangles += 1
                if a == b or b == c or c == a:
                    continue  # collapsed by the weld: a sliver thinner than the tolerance
                for u, v in ((a, b), (b, c), (c, a)):
                    e = (min(u, v), max(u, v))
                    edges[e] = edges.get(e, 0) + 1
            offset += len(lst["points"])
        bad = sum(1 for n in edges.values() if (n % 2 == 1 if odd_only else n != 2))
        result.append((triangles, bad))
    return result


def check_max_pieces(surface, max_pieces):
    """The last frame has at most max_pieces pieces (grouped as closed_pieces groups them)."""
    n = len(piece_lists(surface))
    ok = n <= max_pieces
    print(f"max pieces: last frame has {n} pieces, at most {max_pieces} allowed: {'ok' if ok else 'FAILED'}")
    return ok


def strict_closed_counts(piece, min_area=1e-14):
    """For one piece (from piece_lists): (triangles, zero-area triangles, bad edges, {triangles
    per bad edge: edges}). Vertices are welded only where their recorded coordinates are exactly
    equal; a triangle is zero-area when its welded corners repeat or its area is below min_area
    (m²); bad edges are the undirected edges of the other triangles not in exactly two of them."""
    import numpy as np
    points, triangles, offset = [], [], 0
    for lst in piece["lists"]:
        points.append(np.array([[p["x"], p["y"], p["z"]] for p in lst["points"]], dtype=np.float64).reshape(-1, 3))
        triangles.append(np.array(lst["indices"], dtype=np.int64).reshape(-1, 3) + offset)
        offset += len(lst["points"])
    points = np.concatenate(points)
    triangles = np.concatenate(triangles)
    if len(triangles) == 0:
        return 0, 0, 0, {}
    _, weld = np.unique(points, axis=0, return_inverse=True)
    t = weld.reshape(-1)[triangles]
    corners = points[triangles]
    area = 0.5 * np.linalg.norm(np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0]), axis=1)
    repeated = (t[:, 0] == t[:, 1]) | (t[:, 1] == t[:, 2]) | (t[:, 2] == t[:, 0])
    zero = repeated | (area < min_area)
    kept = t[~zero]
    edges = np.concatenate([kept[:, [0, 1]], kept[:, [1, 2]], kept[:, [2, 0]]])
    edges.sort(axis=1)
    _, uses = np.unique(edges, axis=0, return_counts=True)
    bad_uses = uses[uses != 2]
    histogram = {int(n): int(c) for n, c in zip(*np.unique(bad_uses, return_counts=True))}
    return len(t), int(zero.sum()), int(len(bad_uses)), histogram


def check_strict_closed(surface):
    """Every piece of the last frame is a closed manifold without degenerate triangles as a reader
    of the f32 recording sees it (see strict_closed_counts). After all cuts, so an edge in four
    triangles (two coinciding sheets of an unfinished cut) is bad too."""
    pieces = piece_lists(surface)
    total_zero = total_bad = 0
    for k, piece in enumerate(pieces):
        triangles, zero, bad, histogram = strict_closed_counts(piece)
        total_zero += zero
        total_bad += bad
        if zero or bad:
            uses = ", ".join(f"{c} in {n}" for n, c in sorted(histogram.items()))
            print(f"strict closed: piece {k} ({triangles} triangles): {zero} zero-area triangles, "
                  f"{bad} edges not in exactly two triangles" + (f" ({uses})" if uses else ""))
    ok = total_zero == 0 and total_bad == 0
    print(f"strict closed: last frame, {len(pieces)} pieces: {total_zero} zero-area triangles, "
          f"{total_bad} edges not in exactly two triangles in total: {'ok' if ok else 'FAILED'}")
    return ok


def check_energy_after_last_cut(stats, cut_times, pct):
    """E0 = total energy at the first step at or after the last cut; no later step may exceed
    E0 + pct/100 * |E0|."""
    if not cut_times:
        print("energy after last cut: no cut events: FAILED")
        return False
    t_cut = max(cut_times)
    # "At or after", with a nanosecond of slack for times accumulated differently.
    after = [s for s in stats if s["time"] >= t_cut - 1e-9]
    if not after:
        print(f"energy after last cut: no /stats step at or after the last cut (t = {t_cut:.4f} s): FAILED")
        return False
    e0, t0 = after[0]["energy"]["total"], after[0]["time"]
    limit = e0 + pct / 100 * abs(e0)
    later = after[1:]
    if not later:
        print(f"energy after last cut (t = {t_cut:.4f} s): E0 = {e0:.6f} J at t = {t0:.4f} s, no later step: ok")
        return True
    peak = max(later, key=lambda s: s["energy"]["total"])
    e_peak, t_peak = peak["energy"]["total"], peak["time"]
    rise = 100 * (e_peak - e0) / abs(e0) if e0 != 0 else float("inf") if e_peak > e0 else 0.0
    ok = e_peak <= limit
    print(f"energy after last cut (t = {t_cut:.4f} s): E0 = {e0:.6f} J at t = {t0:.4f} s, peak after it "
          f"{e_peak:.6f} J at t = {t_peak:.4f} s ({rise:+.3f} %, at most +{pct:g} % allowed): {'ok' if ok else 'FAILED'}")
    return ok


def piece_meshes(surface):
    """Per piece: (vertices as an n×3 array, triangles as an m×3×3 array), lists grouped as in
    closed_pieces."""
    import numpy as np
    pieces, current = [], None
    for lst in surface["entities"][0]["triangles"]:
        is_cut = lst["color"]["g"] < 0.5
        if current is None or not is_cut or current["has_cut"]:
            current = {"points": [], "triangles": [], "has_cut": False}
            pieces.append(current)
        pts = np.array([[p["x"], p["y"], p["z"]] for p in lst["points"]])
        idx = np.array(lst["indices"]).reshape(-1, 3)
        current["points"].append(pts)
        current["triangles"].append(pts[idx])
        current["has_cut"] = current["has_cut"] or is_cut
    return [(np.concatenate(p["points"]), np.concatenate(p["triangles"])) for p in pieces]


def point_mesh_distance(x, tris):
    """Exact distance from point x to a triangle soup (m×3×3): the plane distance where x projects
    into a triangle, else the distance to its nearest edge."""
    import numpy as np
    a, b, c = tris[:, 0], tris[:, 1], tris[:, 2]
    n = np.cross(b - a, c - a)
    nn = np.einsum("ij,ij->i", n, n)
    ok = nn > 0
    t = np.where(ok, np.einsum("ij,ij->i", x - a, n) / np.where(ok, nn, 1.0), 0.0)
    p = x - t[:, None] * n
    def inside(u, v):
        return np.einsum("ij,ij->i", np.cross(v - u, p - u), n) >= 0
    face = ok & inside(a, b) & inside(b, c) & inside(c, a)
    best = np.where(face, np.abs(t) * np.sqrt(nn), np.inf)
    for u, v in ((a, b), (b, c), (c, a)):
        e = v - u
        ee = np.einsum("ij,ij->i", e, e)
        s = np.clip(np.einsum("ij,ij->i", x - u, e) / np.where(ee > 0, ee, 1.0), 0.0, 1.0)
        q = u + s[:, None] * e
        best = np.minimum(best, np.linalg.norm(x - q, axis=1))
    return float(best.min())


def deepest_inside(surface):
    """The deepest a vertex of one piece lies inside another piece's closed surface (generalized
    winding number > 1/2, depth = distance to that surface)."""
    import numpy as np
    meshes = piece_meshes(surface)
    deepest = 0.0
    for a, (pts, _) in enumerate(meshes):
        for b, (_, tris) in enumerate(meshes):
            if a == b:
                continue
            lo, hi = tris.reshape(-1, 3).min(axis=0), tris.reshape(-1, 3).max(axis=0)
            q = pts[np.all((pts >= lo) & (pts <= hi), axis=1)]
            for start in range(0, len(q), 256):
                chunk = q[start:start + 256]
                A = tris[None, :, 0, :] - chunk[:, None, :]
                B = tris[None, :, 1, :] - chunk[:, None, :]
                C = tris[None, :, 2, :] - chunk[:, None, :]
                la, lb, lc = (np.linalg.norm(X, axis=2) for X in (A, B, C))
                num = np.einsum("ijk,ijk->ij", A, np.cross(B, C))
                den = la * lb * lc + np.einsum("ijk,ijk->ij", A, B) * lc + np.einsum("ijk,ijk->ij", B, C) * la + np.einsum("ijk,ijk->ij", C, A) * lb
                winding = (2.0 * np.arctan2(num, den)).sum(axis=1) / (4.0 * np.pi)
                inside = chunk[winding > 0.5]
                if len(inside) == 0:
                    continue
                d = np.array([point_mesh_distance(x, tris) for x in inside])
                deepest = max(deepest, float(d.max()))
    return deepest


def check_cut(surface, sampled, cuts, stats, min_pieces):
    assert cuts > 0, "no cut events"
    pieces = closed_pieces(surface)
    print(f"cut events: {cuts}; last frame pieces (triangles, open edges): {pieces}")
    assert len(pieces) >= min_pieces, f"expected at least {min_pieces} pieces, got {len(pieces)}"
    for k, (triangles, bad) in enumerate(pieces):
        assert triangles > 0 and bad == 0, f"piece {k} is not closed: {bad} edges not in two triangles"
    # Frames every half second: every piece closed there too. A cut still under way leaves two
    # coinciding sheets whose shared edges have four triangles, so only frames in which every
    # piece is closed or whose open edges all sit in such a crack are accepted: an edge in one
    # or three triangles (a hole, a flap) never is.
    for time, frame in sampled:
        for k, (triangles, bad) in enumerate(closed_pieces(frame, odd_only=True)):
            assert bad == 0, f"t = {time / 1e9:.2f} s: piece {k} has {bad} edges in an odd number of triangles"
    print(f"{len(sampled)} sampled frames: no edge in an odd number of triangles")
    # The body's size: the largest extent of its first recorded surface (before any cut).
    import numpy as np
    first = np.concatenate([m[0] for m in piece_meshes(sampled[0][1])])
    size = float((first.max(axis=0) - first.min(axis=0)).max())
    depth = deepest_inside(surface)
    print(f"last frame: deepest vertex of one piece inside another {depth * 1e3:.3f} mm ({100 * depth / size:.2f} % of the body's {size:.3f} m)")
    assert depth < 0.01 * size, "pieces pass into each other by more than 1 % of the body's size"
    final = stats[-1]
    print(f"final min z {final['surface']['min_z']:.4f} m, kinetic energy {final['energy']['kinetic']:.3e} J")
    assert abs(final["surface"]["min_z"]) < 0.01, "the pieces should rest on the ground"
    assert final["energy"]["kinetic"] < 1e-2, "the pieces should come to rest"


if __name__ == "__main__":
    sys.exit(main())
