"""Physics steps in one compiled loop: MuJoCo's `mj_step`, called from numba through MuJoCo's C library.

The simulator steps the physics in control periods of a few steps, with the controls of every step given
(`sim.engine`). `mujoco.rollout` costs microseconds per call beyond the steps themselves (its arguments
converted, the state set from an array and read back, the solver's warm start cleared); this loop
writes each step's controls into the `MjData` arrays, adds the tyres' grip (`sim.tyre`), calls `mj_step`
and fills the step's row of sensors (`sim.world.SensorRows`: values copied from the data, MuJoCo's IMU, the
contact sensors computed from the step's contact list), with nothing else between the steps. The data
carries on from period to period (the solver's warm start included), as a plain `mj_step` loop does.

`mj_step` and `mj_contactForce` are reached by their addresses in the `libmujoco` the bindings load
(`ctypes`), and the model, the data and their arrays by theirs (`MjModel._address`, `MjData._address`); the
calls are LLVM intrinsics, so the loop keeps no pointer in its compiled code and numba caches it beside
this module. MuJoCo's fatal errors
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
from sim.world import BODY, GEOM, SOURCES, World

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


_LIBRARY = ctypes.CDLL(_library_path())
_MJ_STEP = int(ctypes.cast(_LIBRARY.mj_step, ctypes.c_void_p).value or 0)
"""Address of `mj_step(const mjModel*, mjData*)`."""
_MJ_CONTACT_FORCE = int(ctypes.cast(_LIBRARY.mj_contactForce, ctypes.c_void_p).value or 0)
"""Address of `mj_contactForce(const mjModel*, const mjData*, int id, mjtNum result[6])`."""


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
def _contact_force(
    typingctx: Any, function: Any, model: Any, data: Any, index: Any, result: Any
) -> Any:  # pragma: no cover - compiled
    """Call `mj_contactForce` at address `function` (model, data, contact index, result address)."""
    signature = types.void(types.int64, types.int64, types.int64, types.int64, types.int64)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> None:
        pointer = ir.IntType(8).as_pointer()
        kind = ir.FunctionType(ir.VoidType(), [pointer, pointer, ir.IntType(32), pointer])
        callee = builder.inttoptr(args[0], kind.as_pointer())
        index = builder.trunc(args[3], ir.IntType(32))
        builder.call(callee, [builder.inttoptr(args[1], pointer), builder.inttoptr(args[2], pointer), index,
                              builder.inttoptr(args[4], pointer)])  # fmt: skip

    return signature, codegen


@intrinsic
def _load(typingctx: Any, address: Any) -> Any:  # pragma: no cover - compiled
    """The float64 at `address` (an int64)."""
    signature = types.float64(types.int64)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        return builder.load(builder.inttoptr(args[0], ir.DoubleType().as_pointer()))

    return signature, codegen


@intrinsic
def _load_int(typingctx: Any, address: Any) -> Any:  # pragma: no cover - compiled
    """The int32 at `address` (an int64), widened to int64."""
    signature = types.int64(types.int64)

    def codegen(context: Any, builder: Any, sig: Any, args: Any) -> Any:
        value = builder.load(builder.inttoptr(args[0], ir.IntType(32).as_pointer()))
        return builder.sext(value, ir.IntType(64))

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

_MINVAL = 1e-15
"""MuJoCo's `mjMINVAL`: the least total force a contact sensor's centroid divides by."""


@njit(cache=True, nogil=True)
def _add_tyre_forces(  # pragma: no cover
    state: np.ndarray, tyres: np.ndarray, root: np.ndarray, dt: float, sd: np.ndarray
) -> None:
    """Each tyre's grip (`sim.tyre`) added to its wheel's `xfrc_applied`, from the data's velocities and
    the floor contacts of the row of sensors `sd` (the last step's). `state` (int64): address and length of
    each of qvel, xpos, xmat, xipos, xaxis and xfrc_applied."""
    qvel = carray(_doubles(state[0]), state[1])  # type: ignore[call-arg]
    xpos = carray(_doubles(state[2]), state[3])
    xmat = carray(_doubles(state[4]), state[5])
    xipos = carray(_doubles(state[6]), state[7])
    xaxis = carray(_doubles(state[8]), state[9])
    xfrc = carray(_doubles(state[10]), state[11])
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
def _side(kind: int, ident: int, body: int, geom: int, parent: np.ndarray) -> bool:  # pragma: no cover
    """Whether a contact's body and geom are a sensor side's object (MuJoCo's `checkMatch`): the geom, the
    body, or a body in the subtree of the body."""
    if kind == GEOM:
        return ident == geom
    if kind == BODY:
        return ident == body
    while body > ident:  # XBODY: up the tree from the body (a parent's id is lower than its children's)
        body = parent[body]
    return body == ident


@njit(cache=True, nogil=True)
def _direction(  # pragma: no cover
    sensor: np.ndarray, g1: int, g2: int, b1: int, b2: int, parent: np.ndarray
) -> float:
    """MuJoCo's `matchContact` for a sensor with both sides given: 0.0 when the contact is not between the
    sensor's two objects, 1.0 when its geoms are in the sensor's order, -1.0 when reversed."""
    m11 = _side(sensor[1], sensor[2], b1, g1, parent)
    m12 = _side(sensor[1], sensor[2], b2, g2, parent)
    m21 = _side(sensor[3], sensor[4], b1, g1, parent)
    m22 = _side(sensor[3], sensor[4], b2, g2, parent)
    regular, reverse = m11 and m22, m12 and m21
    if regular:
        return 1.0
    return -1.0 if reverse else 0.0


@njit(cache=True, nogil=True)
def _contact_sensors(  # pragma: no cover
    o: np.ndarray, contacts: np.ndarray, reader: np.ndarray, geom_body: np.ndarray, parent: np.ndarray,
    scratch: np.ndarray,
) -> None:
    """The contact sensors of `contacts` into the row `o`, as MuJoCo's `contact` sensor with data "found
    force pos" and `reduce="netforce"` computes them (the same operations in the same order): the count of
    matching contacts, the sum of their forces rotated to the world frame (negated where the contact's geoms
    are in the reverse order), the centroid of their positions weighted by their forces' norms. `reader`
    (int64): addresses of `mj_contactForce`, the model, the data and the step's contact count, the contact
    list's address, its stride and the offsets of a contact's position, frame and geoms."""
    n = contacts.shape[0]
    wrench = scratch[:6]
    total = scratch[6 : 6 + n]
    for s in range(n):
        c = contacts[s, 0]
        for j in range(7):
            o[c + j] = 0.0
        total[s] = 0.0
    ncon = int(_load(reader[3]))  # type: ignore[call-arg]
    for j in range(ncon):
        at = reader[4] + j * reader[5]
        g1, g2 = _load_int(at + reader[8]), _load_int(at + reader[8] + 4)
        b1 = geom_body[g1] if g1 >= 0 else -1
        b2 = geom_body[g2] if g2 >= 0 else -1
        forced = False
        for s in range(n):
            sign = _direction(contacts[s], g1, g2, b1, b2, parent)
            if sign == 0.0:
                continue
            if not forced:
                _contact_force(reader[0], reader[1], reader[2], j, wrench.ctypes.data)
                forced = True
            f0, f1, f2 = sign * wrench[0], sign * wrench[1], sign * wrench[2]
            weight = np.sqrt(f0 * f0 + f1 * f1 + f2 * f2)
            m = at + reader[7]
            c = contacts[s, 0]
            o[c] += 1.0
            o[c + 1] += _load(m) * f0 + _load(m + 24) * f1 + _load(m + 48) * f2
            o[c + 2] += _load(m + 8) * f0 + _load(m + 32) * f1 + _load(m + 56) * f2
            o[c + 3] += _load(m + 16) * f0 + _load(m + 40) * f1 + _load(m + 64) * f2
            p = at + reader[6]
            o[c + 4] += _load(p) * weight
            o[c + 5] += _load(p + 8) * weight
            o[c + 6] += _load(p + 16) * weight
            total[s] += weight
    for s in range(n):
        c = contacts[s, 0]
        scale = 1.0 / (total[s] if total[s] > _MINVAL else _MINVAL)
        o[c + 4] *= scale
        o[c + 5] *= scale
        o[c + 6] *= scale


@njit(cache=True, nogil=True)
def _copy(copies: np.ndarray, o: np.ndarray) -> None:  # pragma: no cover
    """The values at the addresses of `copies` ((n, 2) int64: row index, address) into the row `o`."""
    for r in range(copies.shape[0]):
        o[copies[r, 0]] = _load(copies[r, 1])  # type: ignore[call-arg]


@njit(cache=True, nogil=True)
def _step_rows(
    layout: np.ndarray, control: np.ndarray, out: np.ndarray, previous: np.ndarray, state: np.ndarray,
    tyres: np.ndarray, root: np.ndarray, dt: float, before: np.ndarray, after: np.ndarray,
    contacts: np.ndarray, reader: np.ndarray, geom_body: np.ndarray, parent: np.ndarray, scratch: np.ndarray,
) -> float:  # pragma: no cover
    """For every row of `out`: the row of `control` into the data's control arrays, the tyres' grip
    (`_add_tyre_forces`, from the previous row's floor contacts: `previous` for the first), the copies read
    before the step (`before`), one `mj_step`, the copies read after it (`after`) and the contact sensors
    (`_contact_sensors`) into the row. `layout` (int64): addresses of `mj_step`, the model and the data,
    then address and length of each of the `_TARGETS` control arrays, then the first index and the count of
    the contact sensors whose found counts are summed (every 7th value). Returns that sum over the steps, or
    -1 at the first step that made a value of its row NaN or infinite."""
    first, count = layout[3 + 2 * _TARGETS], layout[4 + 2 * _TARGETS]
    found = 0.0
    for i in range(out.shape[0]):
        row = control[i]
        at = 0
        for t in range(_TARGETS):
            target = carray(_doubles(layout[3 + 2 * t]), layout[4 + 2 * t])  # type: ignore[call-arg]
            for j in range(target.shape[0]):
                target[j] = row[at + j]
            at += target.shape[0]
        o = out[i]
        if tyres.shape[0]:
            _add_tyre_forces(state, tyres, root, dt, previous if i == 0 else out[i - 1])
        _copy(before, o)
        _mj_step(layout[0], layout[1], layout[2])  # type: ignore[call-arg]
        _copy(after, o)
        _contact_sensors(o, contacts, reader, geom_body, parent, scratch)
        bad = False
        for j in range(o.shape[0]):
            zero = o[j] * 0.0  # NaN for NaN or inf
            bad |= zero != zero
        if bad:
            return -1.0
        for c in range(count):
            found += o[first + 7 * c]
    return found


def _addresses(data: mujoco.MjData, copies: np.ndarray) -> np.ndarray:
    """(n, 2) int64 row index and address of each copy of a `SensorRows` table in the data's arrays."""
    arrays = [getattr(data, name) for name in SOURCES]
    table = np.zeros((len(copies), 2), dtype=np.int64)
    for r, (column, source, index) in enumerate(copies.tolist()):
        array = arrays[source]
        if not 0 <= index < array.size:
            raise ValueError(f"sensor row copy {r}: index {index} outside {SOURCES[source]} ({array.size})")
        table[r] = column, int(array.ctypes.data) + 8 * index
    return table


def _reader(world: World, data: mujoco.MjData) -> np.ndarray:
    """The addresses `_contact_sensors` reads: MuJoCo keeps a step's contact list at the start of the data's
    arena, one address for the data's life (the bindings give it even with no contact)."""
    contact = data.contact
    at = int(contact.dist.ctypes.data)  # a contact's first member
    count = int(data.sensordata.ctypes.data) + 8 * world.rows.contact_count
    offsets = [int(getattr(contact, name).ctypes.data) - at for name in ("pos", "frame", "geom")]
    stride = int(contact.dist.strides[0])
    if stride < 8 * 13:  # a contact holds at least its distance, position and frame
        raise RuntimeError(f"MuJoCo's contact list has a stride of {stride} bytes")
    return np.array(
        [_MJ_CONTACT_FORCE, int(world.model._address), int(data._address), count, at, stride, *offsets],
        dtype=np.int64,
    )


class _RowTables:
    """The addresses and tables `_step_rows` fills a world's rows of sensors from (valid while the data
    lives, which this object keeps)."""

    def __init__(self, world: World, data: mujoco.MjData) -> None:
        rows = world.rows
        self.data = data
        self.width = world.sensors.width
        self.tables = (
            _addresses(data, rows.copies_before), _addresses(data, rows.copies_after), rows.contacts,
            _reader(world, data), np.asarray(world.model.geom_bodyid, dtype=np.int64),
            np.asarray(world.model.body_parentid, dtype=np.int64), np.zeros(6 + len(rows.contacts)),
        )  # fmt: skip

    def read(self) -> np.ndarray:
        """The row of the data's present state."""
        before, after, contacts, reader, geom_body, parent, scratch = self.tables
        row = np.zeros(self.width)
        _copy(before, row)
        _copy(after, row)
        _contact_sensors(row, contacts, reader, geom_body, parent, scratch)
        return row


def sensor_row(world: World, data: mujoco.MjData) -> np.ndarray:
    """The row of sensors (`sim.world.SensorSlices`) of the data's present state, evaluated by `mj_forward`
    (what a step's row holds of the state it stepped from)."""
    return _RowTables(world, data).read()


class Stepper:
    """Steps one world's data in periods of given controls, recording a row of sensors (`sim.world.
    SensorRows`) after every step (see the module)."""

    def __init__(
        self, world: World, data: mujoco.MjData, contacts: tuple[int, int] = (0, 0),
        tyres: Tyres | None = None,
    ) -> None:
        """`contacts`: first index in a row and count of the contact sensors (7 values each: found count,
        net force, centroid) whose found counts `run` sums; `tyres`: the wheels whose grip is added before
        every step (`sim.tyre`; None: none)."""
        model = world.model
        self.model = model
        self.data = data
        targets = (data.ctrl, data.qfrc_applied, data.xfrc_applied, data.mocap_pos)
        ncontrol = int(mujoco.mj_stateSize(model, int(CONTROL_SPEC)))
        if sum(t.size for t in targets) != ncontrol:
            raise RuntimeError("the control arrays are not MuJoCo's control layout")
        if not all(t.dtype == np.float64 and t.flags.c_contiguous for t in (*targets, data.sensordata)):
            raise RuntimeError("MuJoCo's data arrays are not contiguous float64")
        addresses = [_MJ_STEP, int(model._address), int(data._address)]
        for t in targets:
            addresses += [int(t.ctypes.data), int(t.size)]
        first, count = contacts
        width = world.sensors.width
        if count and not (first >= 0 and first + 7 * count <= width):
            raise ValueError(f"contact sensors {contacts} are outside the {width} values of a row")
        addresses += [int(first), int(count)]
        self.layout = np.array(addresses, dtype=np.int64)
        self._widths = (ncontrol, width)
        self._rows = _RowTables(world, data)
        self._state = _state(data)
        """Addresses and lengths of the data's arrays the tyres' grip reads and writes."""
        self._dt = float(model.opt.timestep)
        self._tyres = tyres.table if tyres is not None else np.zeros((0, 6))
        self._root = tyres.root if tyres is not None else np.zeros(2)
        self._arguments = (self._state, self._tyres, self._root, self._dt, *self._rows.tables)
        """`_step_rows`' arguments after the period's arrays."""
        # MuJoCo's automatic reset on a diverged state would put the robot back at its start unseen: a
        # divergence is reported instead (NaN sensors).
        model.opt.disableflags |= int(mujoco.mjtDisableBit.mjDSBL_AUTORESET)

    def run(self, control: np.ndarray, out: np.ndarray, previous: np.ndarray) -> bool:
        """Step once per row of `control` ((k, ncontrol), `CONTROL_SPEC` order, C-contiguous rows), the
        row of sensors after each step into the rows of `out` ((k, width), C-contiguous); `previous`: the
        row of the state before the first step (`sensor_row`'s, or the last step's). Returns whether a
        contact sensor of `contacts` found a contact after any of the steps.

        Raises:
            FloatingPointError: the physics diverged (a sensor became NaN or infinite).
        """
        k, width = out.shape
        ncontrol, row = self._widths
        if control.shape[1] != ncontrol or width != row or control.shape[0] < k:
            shapes = f"controls {control.shape}, sensors {out.shape}"
            raise ValueError(f"{shapes}: the model's rows are {self._widths} wide, at least as many controls")
        if previous.ndim != 1 or previous.shape[0] != row:
            raise ValueError(f"previous row {previous.shape}: a row is {row} values")
        found = _step_rows(self.layout, control, out, previous, *self._arguments)
        if found < 0.0:
            t = self.data.time
            raise FloatingPointError(f"the physics diverged at t = {t:.4f} s (a sensor is not finite)")
        return found > 0.0


def add_tyre_forces(model: mujoco.MjModel, data: mujoco.MjData, tyres: Tyres, row: np.ndarray) -> None:
    """The tyres' grip at the data's present state, from the floor contacts of the row of sensors `row`,
    added to the data's `xfrc_applied`: what the step loop does before each step (`row`: the last step's)."""
    _add_tyre_forces(_state(data), tyres.table, tyres.root, float(model.opt.timestep), row)


def _state(data: mujoco.MjData) -> np.ndarray:
    """Addresses and lengths of qvel, xpos, xmat, xipos, xaxis and xfrc_applied (`_add_tyre_forces`)."""
    arrays = (data.qvel, data.xpos, data.xmat, data.xipos, data.xaxis, data.xfrc_applied)
    return np.array([v for a in arrays for v in (int(a.ctypes.data), int(a.size))], dtype=np.int64)
