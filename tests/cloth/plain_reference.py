"""A deliberately plain, independent implementation of docs/cloth-model.md.

Written from the contract text with Python loops and no shared code with
``replication.cloth``: it is the independent check that the compiled step follows the
contract to round-off. Slow on purpose; tests run it on few steps or a small mesh.
"""

import math


def plain_springs(n):
    """List of (a, b, type) in the contract's definition of the six types."""
    out = []
    for i in range(n):
        for j in range(n):
            p = i * n + j
            if j + 1 < n:
                out.append((p, i * n + j + 1, 0))
            if i + 1 < n:
                out.append((p, (i + 1) * n + j, 1))
            if i + 1 < n and j + 1 < n:
                out.append((p, (i + 1) * n + j + 1, 2))
                out.append((i * n + j + 1, (i + 1) * n + j, 3))
            if j + 2 < n:
                out.append((p, i * n + j + 2, 4))
            if i + 2 < n:
                out.append((p, (i + 2) * n + j, 5))
    return out


def plain_step(x, v, rest, k, tau, n, pinned, mass, gravity, damping, dt):
    """One contract step. x, v: lists of [x, y, z]; rest, k, tau: 6 values each."""
    P = n * n
    pinned_set = {i * n + j for i, j in pinned}
    springs = plain_springs(n)
    force = [[mass * gravity[c] - damping * v[p][c] for c in range(3)] for p in range(P)]
    for a, b, t in springs:
        d = [x[b][c] - x[a][c] for c in range(3)]
        L = math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
        for c in range(3):
            fa = k[t] * (L - rest[t]) * d[c] / L
            force[a][c] += fa
            force[b][c] -= fa
    v1, x1 = [], []
    for p in range(P):
        if p in pinned_set:
            vp = [0.0, 0.0, 0.0]
        else:
            vp = [v[p][c] + dt * force[p][c] / mass for c in range(3)]
        v1.append(vp)
        x1.append([x[p][c] + dt * vp[c] for c in range(3)])
    proposals = [[] for _ in range(P)]
    for a, b, t in springs:
        d = [x1[b][c] - x1[a][c] for c in range(3)]
        L = math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
        target = (1 + tau[t]) * rest[t]
        if L <= target:
            continue
        excess = L - target
        unit = [d[c] / L for c in range(3)]
        a_free, b_free = a not in pinned_set, b not in pinned_set
        if a_free and b_free:
            proposals[a].append([0.5 * excess * unit[c] for c in range(3)])
            proposals[b].append([-0.5 * excess * unit[c] for c in range(3)])
        elif a_free:
            proposals[a].append([excess * unit[c] for c in range(3)])
        elif b_free:
            proposals[b].append([-excess * unit[c] for c in range(3)])
    x2 = []
    for p in range(P):
        moves = proposals[p]
        if moves:
            x2.append([x1[p][c] + sum(m[c] for m in moves) / len(moves) for c in range(3)])
        else:
            x2.append(list(x1[p]))
    v2 = []
    for p in range(P):
        if p in pinned_set:
            v2.append([0.0, 0.0, 0.0])
        else:
            v2.append([(x2[p][c] - x[p][c]) / dt for c in range(3)])
    return x2, v2


def plain_run(n_steps, rest, k, tau, n=17, side=1.5, pinned=((0, 0), (0, 16)), mass=0.001,
              gravity=(0.0, 0.0, -9.81), damping=0.0, dt=0.002, pin_path=None):
    """Roll the plain model out from the flat sheet; returns the list of position frames.

    ``pin_path(step) -> (dx, dy, dz)``: anchors that move (not in the contract): after
    each step the pinned particles are placed at their start plus that offset."""
    h = side / (n - 1)
    x = [[j * h, i * h, 0.0] for i in range(n) for j in range(n)]
    start = [list(p) for p in x]
    v = [[0.0, 0.0, 0.0] for _ in range(n * n)]
    frames = [x]
    for step in range(n_steps):
        x, v = plain_step(x, v, rest, k, tau, n, pinned, mass, gravity, damping, dt)
        if pin_path is not None:
            offset = pin_path(step + 1)
            for i, j in pinned:
                x[i * n + j] = [start[i * n + j][c] + offset[c] for c in range(3)]
        frames.append(x)
    return frames
