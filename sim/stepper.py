"""Physics steps in one compiled loop: MuJoCo's `mj_step`, called from numba through MuJoCo's C library.

The simulator steps the physics in control periods of a few steps, with the controls of every step given
(`sim.engine`). `mujoco.rollout` costs microseconds per call beyond the steps themselves (its arguments
converted, the state set from an array and read back, the solver's warm start cleared); this loop
writes each step's controls into the `MjData` arrays, adds the tyres' grip (`sim.tyre`), calls `mj_step`
and copies the sensors out, with nothing else between the steps. The data carries on from period to period
(the solver's warm start included), as a plain `mj_step` loop does.

`mj_step` is reached by its address in the `libmujoco` the bindings load (`ctypes`), and the model and data
by theirs (`MjModel._address`, `MjData._address`); the call is an LLVM intrinsic (`_mj_step`), so the loop
keeps no pointer in its compiled code and numba caches it beside this module. MuJoCo's fatal errors
(`mju_error`) raise through the bindings but would end the process here; the one a step can meet is its
arena running out, and the worlds reserve 8 MB (`sim.world`) where an episode uses tens of kB.
"""

from __future__ import annotations

import ctypes
import glob
import os
from typing import Any

import mujoco
import numpy as np
from llvmlite import ir
from numba import carray, njit, types
from numba.extending import intrinsic

from sim.tyre import TYRE_SLIP_SPEED, Tyres

CONTROL_SPEC = (
    mujoco.mjtState.mjSTATE_CTRL
    | mujoco.mjtState.mjSTATE_QFRC_APPLIED
    | mujoco.mjtState.mjSTATE_XFRC_APPLIED
    | mujoco.mjtState.mjSTATE_MOCAP_POS
)
"""What a row of controls holds, in this order: ctrl, qfrc_applied, xfrc_applied, mocap_pos."""


def _library_path() -> str:
    """The MuJoCo shared library inside the installed `mujoco` package (the one its bindings load)."""
    folder = os.path.dirname(mujoco.__file__)
    patterns = ("libmujoco.so*", "libmujoco*.dylib")
    found = sorted(path for pattern in patterns for path in glob.glob(os.path.join(folder, pattern)))
    if not found:
        raise RuntimeError(f"no MuJoCo shared library in {folder}")
    return found[0]


_MJ_STEP = int(ctypes.cast(ctypes.CDLL(_library_path()).mj_step, ctypes.c_void_p).value or 0)
"""Address of `mj_step(const mjModel*, mjData*)`."""


@intrinsic
def _mj_step(typingctx: Any, function: Any, model: Any, data: Any) -> Any:  # pragma: no cover - compiled
    """Call the C function at address `function` with the model and data addresses (int64 each)."""
    signature = types.void(types.int64, types.int64, types.int64)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> None:
        pointer = ir.IntType(8).as_pointer()
        callee = builder.inttoptr(args[0], ir.FunctionType(ir.VoidType(), [pointer, pointer]).as_pointer())
        builder.call(callee, [builder.inttoptr(args[1], pointer), builder.inttoptr(args[2], pointer)])

    return signature, codegen


@intrinsic
def _doubles(typingctx: Any, address: Any) -> Any:  # pragma: no cover - compiled
    """The float64 pointer at `address` (an int64), for `numba.carray`."""
    signature = types.CPointer(types.float64)(types.int64)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        return builder.inttoptr(args[0], context.get_value_type(sig.return_type))

    return signature, codegen


_TARGETS = 4
"""Arrays a row of controls fills: ctrl, qfrc_applied, xfrc_applied, mocap_pos (`CONTROL_SPEC`)."""


@njit(cache=True, nogil=True)
def _add_tyre_forces(  # pragma: no cover
    state: np.ndarray, tyres: np.ndarray, root: np.ndarray, dt: float
) -> None:
    """Each tyre's grip (`sim.tyre`) added to its wheel's `xfrc_applied`, from the data's velocities and
    the floor contacts of the last step. `state` (int64): address and length of each of qvel, xpos, xmat,
    xipos, xaxis, xfrc_applied and sensordata."""
    qvel = carray(_doubles(state[0]), state[1])  # type: ignore[call-arg]
    xpos = carray(_doubles(state[2]), state[3])
    xmat = carray(_doubles(state[4]), state[5])
    xipos = carray(_doubles(state[6]), state[7])
    xaxis = carray(_doubles(state[8]), state[9])
    xfrc = carray(_doubles(state[10]), state[11])
    sd = carray(_doubles(state[12]), state[13])
    rb, rd = int(root[0]), int(root[1])
    bx, by, bz = xpos[3 * rb], xpos[3 * rb + 1], xpos[3 * rb + 2]
    r = 9 * rb
    lx, ly, lz = qvel[rd + 3], qvel[rd + 4], qvel[rd + 5]
    wx = xmat[r] * lx + xmat[r + 1] * ly + xmat[r + 2] * lz
    wy = xmat[r + 3] * lx + xmat[r + 4] * ly + xmat[r + 5] * lz
    wz = xmat[r + 6] * lx + xmat[r + 7] * ly + xmat[r + 8] * lz
    for w in range(tyres.shape[0]):
        body, dof, jnt, s = int(tyres[w, 0]), int(tyres[w, 1]), int(tyres[w, 2]), int(tyres[w, 3])
        mu, g = tyres[w, 4], tyres[w, 5]
        if sd[s] <= 0.0:
            continue
        fx, fy, fz = sd[s + 1], sd[s + 2], sd[s + 3]
        normal = np.sqrt(fx * fx + fy * fy + fz * fz)
        if normal <= 0.0:
            continue
        nx, ny, nz = fx / normal, fy / normal, fz / normal
        if nz < 0.0:
            nx, ny, nz = -nx, -ny, -nz
        px, py, pz = sd[s + 4], sd[s + 5], sd[s + 6]
        cx, cy, cz = xpos[3 * body], xpos[3 * body + 1], xpos[3 * body + 2]
        om = qvel[dof]
        ax, ay, az = om * xaxis[3 * jnt], om * xaxis[3 * jnt + 1], om * xaxis[3 * jnt + 2]
        rx, ry, rz = px - bx, py - by, pz - bz
        qx, qy, qz = px - cx, py - cy, pz - cz
        vx = qvel[rd] + wy * rz - wz * ry + ay * qz - az * qy
        vy = qvel[rd + 1] + wz * rx - wx * rz + az * qx - ax * qz
        vz = qvel[rd + 2] + wx * ry - wy * rx + ax * qy - ay * qx
        vn = vx * nx + vy * ny + vz * nz
        ux, uy, uz = vx - vn * nx, vy - vn * ny, vz - vn * nz
        slip = np.sqrt(ux * ux + uy * uy + uz * uz)
        if slip < 1e-12:
            continue
        t = np.tanh(slip / TYRE_SLIP_SPEED)
        grip = mu * normal * t
        stiffness = mu * normal / TYRE_SLIP_SPEED * (1.0 - t * t)
        scale = -grip / (1.0 + dt * g * stiffness) / slip
        gx, gy, gz = scale * ux, scale * uy, scale * uz
        b = 6 * body
        xfrc[b] += gx
        xfrc[b + 1] += gy
        xfrc[b + 2] += gz
        ox, oy, oz = px - xipos[3 * body], py - xipos[3 * body + 1], pz - xipos[3 * body + 2]
        xfrc[b + 3] += oy * gz - oz * gy
        xfrc[b + 4] += oz * gx - ox * gz
        xfrc[b + 5] += ox * gy - oy * gx


@njit(cache=True, nogil=True)
def _step_rows(
    layout: np.ndarray, control: np.ndarray, out: np.ndarray, state: np.ndarray, tyres: np.ndarray,
    root: np.ndarray, dt: float,
) -> float:  # pragma: no cover
    """For every row of `out`: the row of `control` into the data's control arrays, the tyres' grip
    (`_add_tyre_forces`), one `mj_step`, the data's
    sensors into the row. `layout` (int64): addresses of `mj_step`, the model and the data, then address and
    length of each of the `_TARGETS` control arrays and of `sensordata`, then the first index and the count
    of the contact sensors whose found counts are summed (every 7th value). Returns that sum over the steps,
    or -1 at the first step that made a sensor value NaN or infinite."""
    sensordata = carray(_doubles(layout[3 + 2 * _TARGETS]), layout[4 + 2 * _TARGETS])  # type: ignore[call-arg]
    first, count = layout[5 + 2 * _TARGETS], layout[6 + 2 * _TARGETS]
    found = 0.0
    for i in range(out.shape[0]):
        row = control[i]
        at = 0
        for t in range(_TARGETS):
            target = carray(_doubles(layout[3 + 2 * t]), layout[4 + 2 * t])
            for j in range(target.shape[0]):
                target[j] = row[at + j]
            at += target.shape[0]
        if tyres.shape[0]:
            _add_tyre_forces(state, tyres, root, dt)
        _mj_step(layout[0], layout[1], layout[2])
        total = 0.0
        o = out[i]
        for j in range(sensordata.shape[0]):
            v = sensordata[j]
            o[j] = v
            total += v * 0.0
        if total != 0.0:  # NaN or inf times 0 is NaN
            return -1.0
        for c in range(count):
            found += o[first + 7 * c]
    return found


class Stepper:
    """Steps one model and data in periods of given controls (see the module)."""

    def __init__(
        self, model: mujoco.MjModel, data: mujoco.MjData, contacts: tuple[int, int] = (0, 0),
        tyres: Tyres | None = None,
    ) -> None:
        """`contacts`: first index in sensordata and count of the contact sensors (7 values each: found count,
        net force, centroid) whose found counts `run` sums; `tyres`: the wheels whose grip is added before
        every step (`sim.tyre`; None: none)."""
        self.model = model
        self.data = data
        targets = (data.ctrl, data.qfrc_applied, data.xfrc_applied, data.mocap_pos, data.sensordata)
        ncontrol = int(mujoco.mj_stateSize(model, int(CONTROL_SPEC)))
        if sum(t.size for t in targets[:_TARGETS]) != ncontrol:
            raise RuntimeError("the control arrays are not MuJoCo's control layout")
        if not all(t.dtype == np.float64 and t.flags.c_contiguous for t in targets):
            raise RuntimeError("MuJoCo's data arrays are not contiguous float64")
        addresses = [_MJ_STEP, int(model._address), int(data._address)]
        for t in targets:
            addresses += [int(t.ctypes.data), int(t.size)]
        first, count = contacts
        size = data.sensordata.size
        if count and not (first >= 0 and first + 7 * count <= size):
            raise ValueError(f"contact sensors {contacts} are outside the {size} sensor values")
        addresses += [int(first), int(count)]
        self.layout = np.array(addresses, dtype=np.int64)
        self._widths = (ncontrol, int(size))
        """Addresses and lengths `_step_rows` reads (valid while `data` lives, which this object keeps)."""
        arrays = (data.qvel, data.xpos, data.xmat, data.xipos, data.xaxis, data.xfrc_applied, data.sensordata)
        self._state = np.array([v for a in arrays for v in (int(a.ctypes.data), int(a.size))], dtype=np.int64)
        """Addresses and lengths of the data's arrays the tyres' grip reads and writes."""
        self._dt = float(model.opt.timestep)
        self._tyres = tyres.table if tyres is not None else np.zeros((0, 6))
        self._root = tyres.root if tyres is not None else np.zeros(2)
        # MuJoCo's automatic reset on a diverged state would put the robot back at its start unseen: a
        # divergence is reported instead (NaN sensors).
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)

    def add_tyre_forces(self) -> None:
        """The tyres' grip of the data's present state added to its `xfrc_applied`, as `run` does before
        each step (no tyres: nothing)."""
        if self._tyres.shape[0]:
            _add_tyre_forces(self._state, self._tyres, self._root, self._dt)

    def run(self, control: np.ndarray, out: np.ndarray) -> bool:
        """Step once per row of `control` ((k, ncontrol), `CONTROL_SPEC` order, C-contiguous rows), the
        sensors after each step into the rows of `out` ((k, nsensordata), C-contiguous). Returns whether a
        contact sensor of `contacts` found a contact after any of the steps.

        Raises:
            FloatingPointError: the physics diverged (a sensor became NaN or infinite).
        """
        if (control.shape[1], out.shape[1]) != self._widths or control.shape[0] < out.shape[0]:
            shapes = f"controls {control.shape}, sensors {out.shape}"
            raise ValueError(f"{shapes}: the model's rows are {self._widths} wide, at least as many controls")
        found = _step_rows(
            self.layout, control, out, self._state, self._tyres, self._root, self._dt
        )
        if found < 0.0:
            t = self.data.time
            raise FloatingPointError(f"the physics diverged at t = {t:.4f} s (a sensor is not finite)")
        return found > 0.0
