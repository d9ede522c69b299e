"""The compiled recursive Newton-Euler pass behind :class:`.dynamics.InverseDynamics`:
torques of a batch of states over a flattened tree (:class:`.chain.Kinematics`' arrays,
then each link's mass, centre of mass and inertia).
"""

from __future__ import annotations

import numba
import numpy as np

from arduinobot.planner.kinematics.chain import FIXED, PRISMATIC, REVOLUTE, rodrigues

__all__ = ["LANES", "rnea_batch"]

# states per block of the RNEA kernel (fewer in a smaller batch)
LANES = 64


@numba.njit(cache=True, nogil=True)
def rnea_batch(qs, qds, qdds, gravity, parent, origin, jtype, axis, src, scale, offset,
                mass, com, inertia, out):
    """Torques of many states into ``out`` (shape (m, dof)).

    Block by block of up to :data:`LANES` states: every step of the recursion is a
    loop over the block's states, each value in a scratch row with one entry per state,
    and the loops kept small and without branches (the joint's sines and cosines in their
    own loop, its motion apart from the frame change, Newton-Euler apart from both) so the
    compiler vectorises most: 0.205 -> 0.12 us a state on the five-joint course arm,
    whose verification takes the torques of ~2.5k states a motion. Each state's arithmetic is
    the scalar recursion's, operation for operation (its torques bit for bit, whatever
    its block). ``w[link]`` rows: angular velocity (0:3), angular acceleration (3:6),
    origin linear acceleration (6:9), force (9:12), moment about the origin (12:15),
    the link's origin in its parent's frame (15:18); ``rot[k]`` joint k's rotation
    (row-major 3x3)."""
    nj = parent.shape[0]
    dof = out.shape[1]
    L = max(1, min(LANES, qs.shape[0]))
    w = np.zeros((nj + 1, 18, L))
    rot = np.empty((nj, 9, L))
    tau = np.empty((dof, L))
    v = np.zeros(L)
    vd = np.zeros(L)
    vdd = np.zeros(L)
    for m0 in range(0, qs.shape[0], L):
        nb = min(L, qs.shape[0] - m0)
        for i in range(3):
            for b in range(L):
                w[0, i, b] = 0.0
                w[0, 3 + i, b] = 0.0
                w[0, 6 + i, b] = -gravity[i]  # a fixed base accelerating upwards: gravity
        tau[:, :] = 0.0
        for k in range(nj):
            c = k + 1
            p = parent[k]
            moves = jtype[k] != FIXED and src[k] >= 0
            jk = src[k]
            sk = scale[k]
            for b in range(L):  # lanes past the last state repeat it
                mb = m0 + min(b, nb - 1)
                v[b] = offset[k]
                vd[b] = 0.0
                vdd[b] = 0.0
                if moves:
                    v[b] += sk * qs[mb, jk]
                    vd[b] = sk * qds[mb, jk]
                    vdd[b] = sk * qdds[mb, jk]
            x, y, z = axis[k, 0], axis[k, 1], axis[k, 2]
            o = origin[k]
            # local transform child-in-parent: origin, then the joint motion
            if jtype[k] == REVOLUTE:
                for b in range(L):  # rodrigues is inlined (no 3x3 scratch a lane)
                    j00, j01, j02, j10, j11, j12, j20, j21, j22 = rodrigues(x, y, z, v[b])
                    for i in range(3):
                        a0, a1, a2 = o[i, 0], o[i, 1], o[i, 2]
                        rot[k, 3 * i, b] = a0 * j00 + a1 * j10 + a2 * j20
                        rot[k, 3 * i + 1, b] = a0 * j01 + a1 * j11 + a2 * j21
                        rot[k, 3 * i + 2, b] = a0 * j02 + a1 * j12 + a2 * j22
                    w[c, 15, b], w[c, 16, b], w[c, 17, b] = o[0, 3], o[1, 3], o[2, 3]
            else:
                for b in range(L):
                    for i in range(3):
                        for j in range(3):
                            rot[k, 3 * i + j, b] = o[i, j]
                    rx, ry, rz = o[0, 3], o[1, 3], o[2, 3]
                    if jtype[k] == PRISMATIC:
                        rx += v[b] * (o[0, 0] * x + o[0, 1] * y + o[0, 2] * z)
                        ry += v[b] * (o[1, 0] * x + o[1, 1] * y + o[1, 2] * z)
                        rz += v[b] * (o[2, 0] * x + o[2, 1] * y + o[2, 2] * z)
                    w[c, 15, b], w[c, 16, b], w[c, 17, b] = rx, ry, rz
            revolute = jtype[k] == REVOLUTE
            fixed = jtype[k] == FIXED
            mc = mass[c]
            mx, my, mz = com[c, 0], com[c, 1], com[c, 2]
            i00, i01, i02 = inertia[c, 0, 0], inertia[c, 0, 1], inertia[c, 0, 2]
            i10, i11, i12 = inertia[c, 1, 0], inertia[c, 1, 1], inertia[c, 1, 2]
            i20, i21, i22 = inertia[c, 2, 0], inertia[c, 2, 1], inertia[c, 2, 2]
            wp, wc, rk = w[p], w[c], rot[k]
            for b in range(L):
                rx, ry, rz = wc[15, b], wc[16, b], wc[17, b]
                # the parent's motion carried to the child origin, in the parent frame:
                # a_p + dw_p x r + w_p x (w_p x r)
                wx, wy, wz = wp[0, b], wp[1, b], wp[2, b]
                dx, dy, dz = wp[3, b], wp[4, b], wp[5, b]
                tx, ty, tz = wy * rz - wz * ry, wz * rx - wx * rz, wx * ry - wy * rx
                ax = wp[6, b] + (dy * rz - dz * ry) + (wy * tz - wz * ty)
                ay = wp[7, b] + (dz * rx - dx * rz) + (wz * tx - wx * tz)
                az = wp[8, b] + (dx * ry - dy * rx) + (wx * ty - wy * tx)
                # rotated into the child frame (R^T)
                r00, r01, r02 = rk[0, b], rk[1, b], rk[2, b]
                r10, r11, r12 = rk[3, b], rk[4, b], rk[5, b]
                r20, r21, r22 = rk[6, b], rk[7, b], rk[8, b]
                cwx = r00 * wx + r10 * wy + r20 * wz
                cwy = r01 * wx + r11 * wy + r21 * wz
                cwz = r02 * wx + r12 * wy + r22 * wz
                cdx = r00 * dx + r10 * dy + r20 * dz
                cdy = r01 * dx + r11 * dy + r21 * dz
                cdz = r02 * dx + r12 * dy + r22 * dz
                cax = r00 * ax + r10 * ay + r20 * az
                cay = r01 * ax + r11 * ay + r21 * az
                caz = r02 * ax + r12 * ay + r22 * az
                wc[0, b], wc[1, b], wc[2, b] = cwx, cwy, cwz
                wc[3, b], wc[4, b], wc[5, b] = cdx, cdy, cdz
                wc[6, b], wc[7, b], wc[8, b] = cax, cay, caz
            # the joint's own motion; w x s with w still the parent's, in the child frame
            if revolute:
                for b in range(L):
                    cwx, cwy, cwz = wc[0, b], wc[1, b], wc[2, b]
                    tx, ty, tz = cwy * z - cwz * y, cwz * x - cwx * z, cwx * y - cwy * x
                    wc[3, b] += x * vdd[b] + tx * vd[b]
                    wc[4, b] += y * vdd[b] + ty * vd[b]
                    wc[5, b] += z * vdd[b] + tz * vd[b]
                    wc[0, b] = cwx + x * vd[b]
                    wc[1, b] = cwy + y * vd[b]
                    wc[2, b] = cwz + z * vd[b]
            elif not fixed:
                for b in range(L):
                    cwx, cwy, cwz = wc[0, b], wc[1, b], wc[2, b]
                    tx, ty, tz = cwy * z - cwz * y, cwz * x - cwx * z, cwx * y - cwy * x
                    wc[6, b] += x * vdd[b] + 2.0 * tx * vd[b]
                    wc[7, b] += y * vdd[b] + 2.0 * ty * vd[b]
                    wc[8, b] += z * vdd[b] + 2.0 * tz * vd[b]
            for b in range(L):
                cwx, cwy, cwz = wc[0, b], wc[1, b], wc[2, b]
                cdx, cdy, cdz = wc[3, b], wc[4, b], wc[5, b]
                cax, cay, caz = wc[6, b], wc[7, b], wc[8, b]
                # Newton-Euler at the centre of mass, moment about the link origin
                tx, ty, tz = cwy * mz - cwz * my, cwz * mx - cwx * mz, cwx * my - cwy * mx
                fx = mc * (cax + (cdy * mz - cdz * my) + (cwy * tz - cwz * ty))
                fy = mc * (cay + (cdz * mx - cdx * mz) + (cwz * tx - cwx * tz))
                fz = mc * (caz + (cdx * my - cdy * mx) + (cwx * ty - cwy * tx))
                wc[9, b], wc[10, b], wc[11, b] = fx, fy, fz
                iwx = i00 * cwx + i01 * cwy + i02 * cwz
                iwy = i10 * cwx + i11 * cwy + i12 * cwz
                iwz = i20 * cwx + i21 * cwy + i22 * cwz
                wc[12, b] = (i00 * cdx + i01 * cdy + i02 * cdz + (cwy * iwz - cwz * iwy)
                             + (my * fz - mz * fy))
                wc[13, b] = (i10 * cdx + i11 * cdy + i12 * cdz + (cwz * iwx - cwx * iwz)
                             + (mz * fx - mx * fz))
                wc[14, b] = (i20 * cdx + i21 * cdy + i22 * cdz + (cwx * iwy - cwy * iwx)
                             + (mx * fy - my * fx))
        for k in range(nj - 1, -1, -1):
            c = k + 1
            p = parent[k]
            wp, wc, rk = w[p], w[c], rot[k]
            ax0, ax1, ax2 = axis[k, 0], axis[k, 1], axis[k, 2]
            if jtype[k] != FIXED and src[k] >= 0:
                jk, sk = src[k], scale[k]
                if jtype[k] == REVOLUTE:
                    for b in range(L):
                        tau[jk, b] += sk * (ax0 * wc[12, b] + ax1 * wc[13, b] + ax2 * wc[14, b])
                else:
                    for b in range(L):
                        tau[jk, b] += sk * (ax0 * wc[9, b] + ax1 * wc[10, b] + ax2 * wc[11, b])
            if p == 0:
                continue  # the root is fixed: its wrench is the base reaction
            for b in range(L):  # the wrench into the parent frame (R)
                fx, fy, fz = wc[9, b], wc[10, b], wc[11, b]
                nx, ny, nz = wc[12, b], wc[13, b], wc[14, b]
                r00, r01, r02 = rk[0, b], rk[1, b], rk[2, b]
                r10, r11, r12 = rk[3, b], rk[4, b], rk[5, b]
                r20, r21, r22 = rk[6, b], rk[7, b], rk[8, b]
                gx = r00 * fx + r01 * fy + r02 * fz
                gy = r10 * fx + r11 * fy + r12 * fz
                gz = r20 * fx + r21 * fy + r22 * fz
                rx, ry, rz = wc[15, b], wc[16, b], wc[17, b]
                wp[9, b] += gx
                wp[10, b] += gy
                wp[11, b] += gz
                wp[12, b] += r00 * nx + r01 * ny + r02 * nz + (ry * gz - rz * gy)
                wp[13, b] += r10 * nx + r11 * ny + r12 * nz + (rz * gx - rx * gz)
                wp[14, b] += r20 * nx + r21 * ny + r22 * nz + (rx * gy - ry * gx)
        for b in range(nb):
            for i in range(dof):
                out[m0 + b, i] = tau[i, b]
