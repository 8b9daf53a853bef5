"""Prototype check of 3D mean value coordinates (Ju-Schaefer-Warren 2005 / Floater-Kos-Reimers 2005)
as used by Wicke et al. 2007, with analytic gradients: the numbers of docs/math/mean-value.md §7.
Run: python3 docs/math/prototypes/mean_value_check.py (needs numpy). Not part of any build."""
import itertools
import numpy as np

np.set_printoptions(precision=3, linewidth=150)
EPS = np.finfo(float).eps


# ---------------------------------------------------------------- polyhedra
def poly_from_planes(N, b):
    """Convex polyhedron {x : N x <= b}; returns vertices and faces (CCW seen from outside)."""
    N = np.asarray(N, float); b = np.asarray(b, float)
    V = []
    for i, j, k in itertools.combinations(range(len(b)), 3):
        A = N[[i, j, k]]
        if abs(np.linalg.det(A)) < 1e-12:
            continue
        p = np.linalg.solve(A, b[[i, j, k]])
        if np.all(N @ p <= b + 1e-9) and not any(np.linalg.norm(p - q) < 1e-9 for q in V):
            V.append(p)
    V = np.array(V)
    faces = []
    for f in range(len(b)):
        idx = [i for i in range(len(V)) if abs(N[f] @ V[i] - b[f]) < 1e-9]
        if len(idx) < 3:
            continue
        c = V[idx].mean(0); n = N[f] / np.linalg.norm(N[f])
        e1 = V[idx[0]] - c; e1 /= np.linalg.norm(e1); e2 = np.cross(n, e1)
        ang = [np.arctan2((V[i] - c) @ e2, (V[i] - c) @ e1) for i in idx]
        faces.append([idx[a] for a in np.argsort(ang)])   # CCW around outward n
    return V, faces


def fan(faces):
    return [(f[0], f[m], f[m + 1]) for f in faces for m in range(1, len(f) - 1)]


def cube():
    N = np.vstack([np.eye(3), -np.eye(3)]); return poly_from_planes(N, [1, 1, 1, 0, 0, 0])


def cut_cube():
    N = np.vstack([np.eye(3), -np.eye(3), [1, 1, 1]]); return poly_from_planes(N, [1, 1, 1, 0, 0, 0, 2.4])


def tet_from_points(P):
    """The tetrahedron on corners P as outward half-spaces."""
    c = P.mean(0); N = []; b = []
    for f in itertools.combinations(range(4), 3):
        n = np.cross(P[f[1]] - P[f[0]], P[f[2]] - P[f[0]])
        if n @ (P[f[0]] - c) < 0: n = -n
        N.append(n); b.append(n @ P[f[0]])
    return poly_from_planes(N, b)


def regular_tet():
    return tet_from_points(np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], float))


def skew_tet():
    return tet_from_points(np.array([[0, 0, 0], [2.0, 0.1, 0], [0.3, 1.5, 0.2], [0.4, 0.5, 1.7]]))


def diameter(V):
    return max(np.linalg.norm(a - c) for a in V for c in V)


def skew(a):
    return np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])


# ---------------------------------------------------------------- JSW form with analytic gradient
def mvc(x, V, tris, grad=True):
    """Weights w_i = sum_T (d_j x d_k).m_T / det[d_i,d_j,d_k]  (doc eq. 6), lambda, grad lambda."""
    k = len(V); w = np.zeros(k); gw = np.zeros((k, 3))
    d = V - x; r = np.linalg.norm(d, axis=1); u = d / r[:, None]
    I = np.eye(3)
    for T in tris:
        m = np.zeros(3); Jm = np.zeros((3, 3))
        for a in range(3):
            p, q = T[a], T[(a + 1) % 3]
            cr = np.cross(d[p], V[q] - V[p])          # = d_p x d_q, accurate form
            s_cr = np.linalg.norm(cr); nu = cr / s_cr
            sn = np.linalg.norm(np.cross(u[p], u[q])); co = u[p] @ u[q]
            th = np.arctan2(sn, co)
            m += 0.5 * th * nu
            if grad:
                Pp = I - np.outer(u[p], u[p]); Pq = I - np.outer(u[q], u[q])
                gth = (Pp @ u[q] / r[p] + Pq @ u[p] / r[q]) / sn
                Jnu = (I - np.outer(nu, nu)) @ (-skew(V[p] - V[q])) / s_cr
                Jm += 0.5 * (np.outer(nu, gth) + th * Jnu)
        D = d[T[0]] @ np.cross(d[T[1]], d[T[2]])
        gD = -np.cross(V[T[1]] - V[T[0]], V[T[2]] - V[T[0]])
        for a in range(3):
            i, j, l = T[a], T[(a + 1) % 3], T[(a + 2) % 3]
            g = np.cross(d[j], d[l])
            wi = g @ m / D
            w[i] += wi
            if grad:
                gw[i] += (np.cross(V[j] - V[l], m) + Jm.T @ g - wi * gD) / D
    W = w.sum(); lam = w / W
    glam = (gw - np.outer(lam, gw.sum(0))) / W
    return lam, glam, w, gw


# ---------------------------------------------------------------- the paper's eqs (7),(8),(20)-(22)
def one_rings(k, tris):
    rings = []
    for i in range(k):
        nxt = {}
        for T in tris:
            if i in T:
                a = T.index(i); nxt[T[(a + 1) % 3]] = T[(a + 2) % 3]
        j0 = next(iter(nxt)); ring = [j0]
        while nxt[ring[-1]] != j0:
            ring.append(nxt[ring[-1]])
        rings.append(ring)
    return rings


def paper(x, V, rings):
    def Vol(a, b, c):    # V(x_a,x_b,x_c,x), signed
        return np.linalg.det(np.array([V[b] - V[a], V[c] - V[a], x - V[a]])) / 6

    def gVol(a, b, c):   # corrected eq. (21): a vector
        return np.cross(V[b] - V[a], V[c] - V[a]) / 6

    def c_(a, b):
        da, db = x - V[a], x - V[b]
        return np.linalg.norm(np.cross(da, db)) / 6 * np.arccos(np.clip(da @ db / np.linalg.norm(da) / np.linalg.norm(db), -1, 1))

    def gc(a, b):        # eq. (22) as printed
        da, db = x - V[a], x - V[b]; na, nb = np.linalg.norm(da), np.linalg.norm(db)
        ha, hb = da / na, db / nb; cr = np.cross(ha, hb)
        al = np.arccos(np.clip(ha @ hb, -1, 1))
        return ((ha @ hb) * (ha * nb + hb * na) - da - db + al / np.linalg.norm(cr) * np.cross(cr, V[b] - V[a])) / 6

    k = len(V); w = np.zeros(k); gw = np.zeros((k, 3))
    for i, ring in enumerate(rings):
        n = len(ring)
        for t in range(n):
            jm, j, jp = ring[t - 1], ring[t], ring[(t + 1) % n]
            A = Vol(i, j, jp); B = Vol(i, jm, j); C = Vol(jm, jp, j)
            w[i] += c_(j, jp) / A + c_(i, j) * C / (B * A)
            gw[i] += (gc(j, jp) * A - c_(j, jp) * gVol(i, j, jp)) / A**2 \
                + (gc(i, j) * C + c_(i, j) * gVol(jm, jp, j)) * B * A / (B**2 * A**2) \
                - c_(i, j) * C * (B * gVol(i, j, jp) + gVol(i, jm, j) * A) / (B**2 * A**2)
    W = w.sum()
    return w / W, (gw - np.outer(w / W, gw.sum(0))) / W, w


# ---------------------------------------------------------------- polygon-face alternative (not in the paper)
def mvc2d(y, P):
    n = len(P); s = P - y; r = np.linalg.norm(s, axis=1)
    if r.min() < 1e-300:
        e = np.zeros(n); e[r.argmin()] = 1; return e
    t = np.zeros(n)
    for j in range(n):
        a, b = s[j], s[(j + 1) % n]
        t[j] = (r[j] * r[(j + 1) % n] - a @ b) / np.linalg.norm(np.cross(a, b))
    w = np.array([(t[j - 1] + t[j]) / r[j] for j in range(n)])
    return w / w.sum()


def mvc_poly(x, V, faces):
    """w_j += mu_j(y_f) (n_f.m_f)/h_f, y_f = x + h_f m_f/(n_f.m_f), mu = 2D MVC of the face polygon."""
    k = len(V); w = np.zeros(k); d = V - x
    for f in faces:
        m = np.zeros(3)
        for a in range(len(f)):
            p, q = f[a], f[(a + 1) % len(f)]
            cr = np.cross(d[p], V[q] - V[p]); nu = cr / np.linalg.norm(cr)
            up, uq = d[p] / np.linalg.norm(d[p]), d[q] / np.linalg.norm(d[q])
            m += 0.5 * np.arctan2(np.linalg.norm(np.cross(up, uq)), up @ uq) * nu
        n = np.cross(V[f[1]] - V[f[0]], V[f[2]] - V[f[0]]); n /= np.linalg.norm(n)
        h = n @ d[f[0]]; nm = n @ m
        y = x + h / nm * m
        w[f] += mvc2d(y, V[f]) * nm / h
    return w / w.sum(), w


# ---------------------------------------------------------------- helpers
def inside_points(V, faces, n, rng, margin=0.02):
    lo, hi = V.min(0), V.max(0); out = []
    planes = []
    for f in faces:
        nn = np.cross(V[f[1]] - V[f[0]], V[f[2]] - V[f[0]]); nn /= np.linalg.norm(nn); planes.append((nn, nn @ V[f[0]]))
    D = diameter(V)
    while len(out) < n:
        p = lo + (hi - lo) * rng.random(3)
        if all(nn @ p <= bb - margin * D for nn, bb in planes):
            out.append(p)
    return np.array(out)


def fd_grad(fun, x, h):
    g = np.zeros((len(fun(x)), 3))
    for a in range(3):
        e = np.zeros(3); e[a] = h
        g[:, a] = (fun(x + e) - fun(x - e)) / (2 * h)
    return g


def bary(x, P):
    A = np.vstack([P.T, np.ones(4)]); return np.linalg.solve(A, np.append(x, 1))


def trilinear(x):
    out = []
    for v in itertools.product([0, 1], repeat=3):
        out.append(np.prod([x[a] if v[a] else 1 - x[a] for a in range(3)]))
    return np.array(out)


rng = np.random.default_rng(1)
shapes = {"unit cube": cube(), "regular tet": regular_tet(), "skew tet": skew_tet(), "cut cube": cut_cube()}

print("== interior: partition of unity, linear precision, positivity, gradients (200 random points each)")
for name, (V, faces) in shapes.items():
    tris = fan(faces); rings = one_rings(len(V), tris); D = diameter(V)
    X = inside_points(V, faces, 200, rng)
    pu = lp = gerr = gsum = glin = perr = pgrad = poly_lp = 0.0; minlam = 1.0; ratio_spread = 0.0
    for x in X:
        lam, gl, w, gw = mvc(x, V, tris)
        pu = max(pu, abs(lam.sum() - 1)); lp = max(lp, np.linalg.norm(lam @ V - x) / D)
        minlam = min(minlam, lam.min())
        fd = fd_grad(lambda z: mvc(z, V, tris, grad=False)[0], x, 1e-5 * D)
        gerr = max(gerr, np.abs(gl - fd).max() / np.abs(gl).max())
        gsum = max(gsum, np.abs(gl.sum(0)).max() * D)
        glin = max(glin, np.abs(V.T @ gl - np.eye(3)).max())   # sum_i v_i grad(lam_i)^T = I
        lp_, gp_, wp_ = paper(x, V, rings)
        ratio = wp_ / w; ratio_spread = max(ratio_spread, np.ptp(ratio) / abs(ratio.mean()))
        perr = max(perr, np.abs(lp_ - lam).max()); pgrad = max(pgrad, np.abs(gp_ - gl).max() / np.abs(gl).max())
        lpoly, _ = mvc_poly(x, V, faces); poly_lp = max(poly_lp, np.linalg.norm(lpoly @ V - x) / D)
    print(f"{name:12s} k={len(V):2d} faces={[len(f) for f in faces]}  |sum-1|={pu:.1e}  |sum lam v - x|/diam={lp:.1e} "
          f"min lam={minlam:.2e}  grad rel err vs FD={gerr:.1e}  |sum grad|*diam={gsum:.1e}  |sum v grad^T - I|={glin:.1e}")
    print(f"{'':12s} paper eq.(7) w / JSW w: spread {ratio_spread:.1e} (ratio {ratio.mean():.4f}); lam diff {perr:.1e}; "
          f"eq.(20)-(22) grad rel diff {pgrad:.1e};  polygon-face variant lin. prec. {poly_lp:.1e}")
    if "tet" in name:
        be = bg = 0.0
        for x in X:
            lam, gl, _, _ = mvc(x, V, tris)
            be = max(be, np.abs(lam - bary(x, V)).max())
            A = np.vstack([V.T, np.ones(4)]); G = np.linalg.inv(A)[:, :3]   # grad of barycentric coordinates
            bg = max(bg, np.abs(gl - G).max() / np.abs(G).max())
        print(f"{'':12s} vs barycentric: max |lam - b| = {be:.1e}, max rel |grad lam - grad b| = {bg:.1e}")

# ---------------------------------------------------------------- cube vs trilinear
V, faces = cube(); tris = fan(faces)
order = [int(np.argmin(np.linalg.norm(V - np.array(v), axis=1))) for v in itertools.product([0, 1], repeat=3)]
X = inside_points(V, faces, 2000, rng, margin=0.0)
dev = max(np.abs(mvc(x, V, tris, grad=False)[0][order] - trilinear(x)).max() for x in X)
devp = max(np.abs(mvc_poly(x, V, faces)[0][order] - trilinear(x)).max() for x in X)
c = np.full(3, 0.5)
print("\n== unit cube vs trilinear: max |lam - N_tri| fan-triangulated faces =", f"{dev:.3f}", " polygon faces =", f"{devp:.3f}")
print("   at centre (fan):", mvc(c, V, tris, grad=False)[0][order], " (polygon faces):", mvc_poly(c, V, faces)[0][order])
# two triangulations of the same cube differ
tris2 = [(f[1], f[2], f[3]) for f in faces] + [(f[1], f[3], f[0]) for f in faces]
x = np.array([0.3, 0.6, 0.7])
print("   fan from corner 0 vs corner 1 at (0.3,0.6,0.7): max diff",
      f"{np.abs(mvc(x, V, tris, grad=False)[0] - mvc(x, V, tris2, grad=False)[0]).max():.3e}")

# ---------------------------------------------------------------- near the boundary
print("\n== approach to the boundary (cut cube, fan-triangulated).  err = max_i |lam_i - limit_i|, |grad| = max |grad lam_i| * diam")
V, faces = cut_cube(); tris = fan(faces); D = diameter(V); k = len(V)
cen = V.mean(0)
pent = max(faces, key=len)
nf = np.cross(V[pent[1]] - V[pent[0]], V[pent[2]] - V[pent[0]]); nf /= np.linalg.norm(nf)
# face point: inside the first fan triangle of the pentagon; limit = barycentric in that triangle
T0 = tris[[i for i, T in enumerate(tris) if set(T) <= set(pent)][0]]
pface = 0.5 * V[T0[0]] + 0.3 * V[T0[1]] + 0.2 * V[T0[2]]
lim_face = np.zeros(k); lim_face[list(T0)] = [0.5, 0.3, 0.2]
# same point, polygon-face variant: limit = 2D MVC of the pentagon
lim_face_poly = np.zeros(k); lim_face_poly[pent] = mvc2d(pface, V[pent])
# edge point: on an edge of the pentagon shared with the triangle face, at 0.35 along
a, b = pent[0], pent[1]
pedge = 0.65 * V[a] + 0.35 * V[b]; lim_edge = np.zeros(k); lim_edge[a] = 0.65; lim_edge[b] = 0.35
vtx = pent[0]; lim_v = np.zeros(k); lim_v[vtx] = 1
cases = [("face", pface, -nf, lim_face), ("edge", pedge, None, lim_edge), ("vertex", V[vtx], None, lim_v)]
for name, p0, dirn, lim in cases:
    if dirn is None:
        dirn = cen - p0; dirn /= np.linalg.norm(dirn)
    row = []
    for t in [1e-3, 1e-6, 1e-9, 1e-12]:
        x = p0 + t * D * dirn
        lam, gl, _, _ = mvc(x, V, tris)
        # FD check at a step well below the distance
        fd = fd_grad(lambda z: mvc(z, V, tris, grad=False)[0], x, 1e-2 * t * D) if t >= 1e-6 else None
        ge = np.abs(gl - fd).max() / np.abs(gl).max() if fd is not None else float("nan")
        extra = ""
        if name == "face":
            lp, _ = mvc_poly(x, V, faces); extra = f" poly-variant err {np.abs(lp - lim_face_poly).max():.1e}"
        row.append(f"  d={t:.0e}: err {np.abs(lam - lim).max():.1e} |grad| {np.abs(gl).max() * D:.2f} FD {ge:.0e}{extra}")
    print(name); print("\n".join(row))

# gradient near an edge depends on the direction of approach
print("\n== gradient at the edge point from different directions (d=1e-9 diam): max |grad lam| * diam, grad of lam_a")
fa = [f for f in faces if a in f and b in f]
for f in fa:
    n1 = np.cross(V[f[1]] - V[f[0]], V[f[2]] - V[f[0]]); n1 /= np.linalg.norm(n1)
    inward = cen - pedge; inward -= (inward @ n1) * n1   # direction along the face, inward
    inward -= (inward @ (V[b] - V[a])) * (V[b] - V[a]) / np.linalg.norm(V[b] - V[a])**2; inward /= np.linalg.norm(inward)
    x = pedge + 1e-9 * D * (0.999 * inward - 0.0447 * n1)
    lam, gl, _, _ = mvc(x, V, tris)
    print(f"  along face {len(f)}-gon: |grad|*D = {np.abs(gl).max() * D:.3f}, grad lam_a * D = {gl[a] * D}")

# ---------------------------------------------------------------- integration
print("\n== integration: paper's rule (16) (weights times V_e) vs refined centroid-fan rule")
TET4 = (np.array([[0.5854101966249685, 0.1381966011250105, 0.1381966011250105],
                  [0.1381966011250105, 0.5854101966249685, 0.1381966011250105],
                  [0.1381966011250105, 0.1381966011250105, 0.5854101966249685],
                  [0.1381966011250105, 0.1381966011250105, 0.1381966011250105]]), np.full(4, 0.25))


def subdivide(tet):
    p = list(tet); m = {(i, j): 0.5 * (p[i] + p[j]) for i in range(4) for j in range(i + 1, 4)}
    q = lambda i, j: m[(min(i, j), max(i, j))]
    out = [[p[0], q(0, 1), q(0, 2), q(0, 3)], [p[1], q(0, 1), q(1, 2), q(1, 3)], [p[2], q(0, 2), q(1, 2), q(2, 3)],
           [p[3], q(0, 3), q(1, 3), q(2, 3)],
           [q(0, 1), q(0, 2), q(0, 3), q(1, 3)], [q(0, 1), q(0, 2), q(1, 2), q(1, 3)],
           [q(0, 2), q(0, 3), q(1, 3), q(2, 3)], [q(0, 2), q(1, 2), q(1, 3), q(2, 3)]]
    return [np.array(t) for t in out]


def fan_rule(V, tris, c, levels):
    pts, wts = [], []
    tets = [np.array([c, V[T[0]], V[T[1]], V[T[2]]]) for T in tris]
    for _ in range(levels):
        tets = [s for t in tets for s in subdivide(t)]
    for t in tets:
        vol = abs(np.linalg.det(t[1:] - t[0])) / 6
        for bc, wq in zip(*TET4):
            pts.append(t[0] + (t[1:] - t[0]).T @ bc); wts.append(wq * vol)
    return np.array(pts), np.array(wts)


def paper_rule(V, tris, c):
    Ve = sum(abs(np.linalg.det(np.array([V[T[0]] - c, V[T[1]] - c, V[T[2]] - c]))) / 6 for T in tris)
    pts, wts = [], []
    mu = np.zeros(len(V))
    for T in tris:
        vol = abs(np.linalg.det(np.array([V[T[0]] - c, V[T[1]] - c, V[T[2]] - c]))) / 6
        for i in T: mu[i] += vol / (3 * Ve)
        pts.append(0.9 * V[list(T)].mean(0) + 0.1 * c); wts.append(0.5 * vol / Ve * Ve)
    for i in range(len(V)):
        pts.append(0.8 * V[i] + 0.2 * c); wts.append(0.5 * mu[i] * Ve)
    return np.array(pts), np.array(wts), mu, Ve


def integrals(V, tris, pts, wts):
    k = len(V); K = np.zeros((k, k)); M = np.zeros((k, k)); L = np.zeros(k); G = np.zeros((k, 3))
    for p, wq in zip(pts, wts):
        lam, gl, _, _ = mvc(p, V, tris)
        K += wq * gl @ gl.T; M += wq * np.outer(lam, lam); L += wq * lam; G += wq * gl
    return K, M, L, G


def exact_boundary_grad(V, tris):
    """int_P grad lam_i dV = oint lam_i n dA; lam is linear on each boundary triangle."""
    G = np.zeros((len(V), 3))
    for T in tris:
        an = 0.5 * np.cross(V[T[1]] - V[T[0]], V[T[2]] - V[T[0]])
        for i in T: G[i] += an / 3
    return G


for name in ["unit cube", "cut cube", "skew tet"]:
    V, faces = shapes[name]; tris = fan(faces)
    c = V.mean(0)
    Gex = exact_boundary_grad(V, tris)
    ref = None
    for lev in [0, 1, 2]:
        pts, wts = fan_rule(V, tris, c, lev)
        K, M, L, G = integrals(V, tris, pts, wts)
        if ref is not None:
            print(f"  {name}: fan level {lev} ({len(pts)} pts) change in K {np.linalg.norm(K - ref[0]) / np.linalg.norm(K):.1e}, "
                  f"M {np.linalg.norm(M - ref[1]) / np.linalg.norm(M):.1e}; patch residual |G - G_exact|/|G_exact| "
                  f"{np.linalg.norm(G - Gex) / np.linalg.norm(Gex):.1e}")
        ref = (K, M, L, G)
    Kr, Mr, Lr, Gr = ref
    pts, wts, mu, Ve = paper_rule(V, tris, c)
    K, M, L, G = integrals(V, tris, pts, wts)
    print(f"  {name}: paper rule ({len(pts)} pts, weights sum {wts.sum() / Ve:.3f} V_e): K rel err {np.linalg.norm(K - Kr) / np.linalg.norm(Kr):.2e}, "
          f"M rel err {np.linalg.norm(M - Mr) / np.linalg.norm(Mr):.2e}, patch residual {np.linalg.norm(G - Gex) / np.linalg.norm(Gex):.2e}, "
          f"lumped mu_i V_e vs int lam_i: max rel {np.abs(mu * Ve - Lr).max() / Lr.max():.2e}")
