"""A simulated CiA 401 digital I/O module on the `canopen` package (issue 18):
a canopen.LocalNode (SDO server, heartbeat and EMCY producers are canopen's)
with the CiA 401 profile on top: 8 input bytes 0x6000:1..8 sent in TPDO1 on
change (transmission type 255), 8 output bytes 0x6200:1..8 taken from RPDO1,
NMT (boot-up after a reset, PDOs only in operational), and the master's
heartbeat consumed (0x1016): when it is lost every output goes off (the
module's error behaviour) and EMCY 0x8130 is sent.

It shares the drives' bus and recorder (mlipcan.drive.DriveSim): every
input change is recorded with the SYNC count at which its TPDO went out, so
a test can count the periods from the input frame to what the drives did;
the outputs in force are recorded at every SYNC (io.csv: sync, node, time,
outputs 0x6200:1..8 and inputs 0x6000:1..8 as hex), so a test judges what
the module did period by period (issue 19).
A power cycle by injection: N:reboot (defaults, outputs off, boot-up);
N:reboot=PRODUCT: another module in its place (product code 0x1018:02 PRODUCT).
A fault by injection: N:fault=CODE sends EMCY CODE (default 0x5000, device
hardware) and sets the error register 0x1001 to 0x01 (generic error) until
N:fault=off (EMCY 0x0000, error reset; 0x1001 back to 0): the fault is the
hardware's, so it stays through an NMT reset or a power cycle.
Inputs change by injection: N:input=BYTE.BIT=0|1 (BYTE 1..8, BIT 0..7), or
follow a simulated drive's position as a probe touching a surface:
N:probe=BYTE.BIT,DRIVE,COUNTS,below|above (the input is 1 while the drive's
position actual is at or below / at or above COUNTS, evaluated after that
drive's move at every SYNC; off: N:probe=off)."""

import struct
import time
from typing import TYPE_CHECKING

from canopen.objectdictionary import ODArray, ODRecord
from canopen.sdo.exceptions import SdoAbortedError

from canopen import objectdictionary as odm

from . import cia402 as P
from .device import PDO_INVALID, SimDevice, SimNode, new_od, od_identity, od_record, od_var

if TYPE_CHECKING:
    from .drive import DriveSim

U8, U16, U32 = odm.UNSIGNED8, odm.UNSIGNED16, odm.UNSIGNED32
DEVICE_TYPE = 0x00030191  # CiA 401, digital inputs and outputs
NBYTES = 8


def build_od(node_id: int, heartbeat_ms: int = 100) -> odm.ObjectDictionary:
    """CiA 301 communication area and CiA 401 digital I/O (8 bytes each way);
    default PDOs: TPDO1 = 0x6000:1, RPDO1 = 0x6200:1, type 255."""
    od = new_od(node_id, "mlip (simulated I/O module)", "mlip-drive-sim CiA 401 digital I/O")

    def record(name: str, index: int, members: list[tuple[str, int, str, int]]) -> None:
        od_record(od, name, index, members)

    def array(name: str, index: int, access: str) -> None:
        a = ODArray(name, index)
        a.add_member(od_var("Highest sub-index supported", index, 0, U8, "ro", NBYTES))
        for i in range(1, NBYTES + 1):
            a.add_member(od_var(f"{name} {i}", index, i, U8, access, 0, True))
        od.add_object(a)

    od.add_object(od_var("Device type", 0x1000, 0, U32, "ro", DEVICE_TYPE))
    od.add_object(od_var("Error register", 0x1001, 0, U8, "ro", 0))
    od.add_object(od_var("COB-ID EMCY", 0x1014, 0, U32, "rw", 0x80 + node_id))
    record("Consumer heartbeat time", 0x1016, [("Consumer heartbeat time 1", U32, "rw", 0)])
    od.add_object(od_var("Producer heartbeat time", 0x1017, 0, U16, "rw", heartbeat_ms))
    od_identity(od, node_id)
    for kind, com, cob, first in (
        ("RPDO", 0x1400, 0x200 + node_id, 0x62000108),
        ("TPDO", 0x1800, 0x180 + node_id, 0x60000108),
    ):
        record(
            f"{kind}1 communication parameter",
            com,
            [(f"COB-ID used by {kind}", U32, "rw", cob), ("Transmission type", U8, "rw", 255)],
        )
        r = ODRecord(f"{kind}1 mapping parameter", com + 0x200)
        r.add_member(od_var("Number of mapped objects", com + 0x200, 0, U8, "rw", 1))
        for i in range(1, NBYTES + 1):
            r.add_member(
                od_var(f"Mapped object {i}", com + 0x200, i, U32, "rw", first if i == 1 else 0)
            )
        od.add_object(r)
    array("Read input 8-bit", 0x6000, "ro")
    array("Write output 8-bit", 0x6200, "rw")
    return od


class IoModule(SimDevice):
    """One CiA 401 module: inputs (set by injection), outputs (from RPDO1)."""

    def __init__(self, sim: "DriveSim", node_id: int, heartbeat_ms: int = 100) -> None:
        super().__init__(sim, node_id)
        self.node = SimNode(self, node_id, build_od(node_id, heartbeat_ms))
        self.inputs = bytearray(NBYTES)
        self.outputs = bytearray(NBYTES)
        self.operational = False
        self.master: tuple[int, int] | None = None  # (producer node, ms)
        self.master_seen: float | None = None
        self.master_lost = False
        self._rpdo_cob: int | None = None
        # the probe's surface: (byte 1..8, bit, drive node, counts, below)
        self.probe: tuple[int, int, int, int, bool] | None = None
        self.error_reg = 0  # 0x1001 while a fault is injected

    # ------------------------------------------------------------ SDO
    def check_write(self, index: int, sub: int, data: bytes) -> None:
        """CiA 301: a PDO's COB-ID changes only while it is invalid, its
        mapping only while invalid with sub 0 = 0; only 0x6000 / 0x6200 whole
        bytes map."""
        val = int.from_bytes(bytes(data), "little")
        if index in (0x1400, 0x1800) and sub == 1:
            self.check_cob_id(index, val)
        elif index in (0x1600, 0x1A00):
            com = index - 0x200
            n_now = self.sim.od_int(self.node, index, "B", 0)
            if not self.od_u32(com, 1) & PDO_INVALID or (sub >= 1 and n_now != 0):
                raise SdoAbortedError(0x06010000)
            want = 0x6200 if index == 0x1600 else 0x6000
            if (
                sub >= 1
                and val
                and not (val >> 16 == want and 1 <= (val >> 8) & 0xFF <= NBYTES and val & 0xFF == 8)
            ):
                raise SdoAbortedError(0x06040041)
            if sub == 0 and val > NBYTES:
                raise SdoAbortedError(0x06090031)

    def written(self, index: int, sub: int, data: bytes) -> None:
        if index == 0x1016:
            self.consumer(int.from_bytes(bytes(data), "little"))
        elif index == 0x6200:
            self.outputs[sub - 1] = data[0]

    # ------------------------------------------------------------ bus
    def _on_nmt(self, can_id: int, data: bytearray, timestamp: float) -> None:
        if not self._for_me(data):
            return
        cmd = data[0]
        nmt = self.node.nmt
        with self.sim.lock:
            if cmd in (P.NMT_RESET_NODE, P.NMT_RESET_COMM):
                # reset communication: the communication area to its defaults;
                # reset node: everything but the inputs (they are physical)
                ds = self.node.data_store
                for k in list(ds):
                    if k != 0x6000 and (cmd == P.NMT_RESET_NODE or 0x1000 <= k <= 0x1FFF):
                        del ds[k]
                self._consumer_off()
                self._error_reg()
                if cmd == P.NMT_RESET_NODE:
                    self.outputs[:] = bytes(NBYTES)
                self._boot("NMT reset")
                return
            if cmd == P.NMT_START:
                nmt.send_command(cmd)
                self._pdo_on()
            elif cmd in (P.NMT_STOP, P.NMT_PREOP):
                nmt.send_command(cmd)
                self._pdo_off()
            if self.hb_stopped:
                nmt.stop_heartbeat()
            self.rec.event(self.id, "nmt", to=nmt.state, why=f"NMT command 0x{cmd:02X}")

    def _pdo_on(self) -> None:
        self._pdo_off()
        cob = self.od_u32(0x1400, 1)
        if not cob & PDO_INVALID:
            self._rpdo_cob = cob & 0x7FF
            self.node.network.subscribe(self._rpdo_cob, self._on_rpdo)
        self.operational = True
        self.rec.event(
            self.id,
            "pdo_maps",
            tpdo=f"0x{self.od_u32(0x1800, 1):08X}",
            rpdo=f"0x{self.od_u32(0x1400, 1):08X}",
        )
        self._send_inputs("operational")  # CiA 401: the inputs once on entering it

    def _pdo_off(self) -> None:
        if self._rpdo_cob is not None:
            self.node.network.unsubscribe(self._rpdo_cob, self._on_rpdo)
            self._rpdo_cob = None
        self.operational = False

    def _send_inputs(self, why: str) -> None:
        """TPDO1 (type 255: on change) with the mapped input bytes."""
        for i in range(NBYTES):
            self.node.data_store.setdefault(0x6000, {})[i + 1] = bytes([self.inputs[i]])
        cob = self.od_u32(0x1800, 1)
        if not self.operational or cob & PDO_INVALID:
            return
        n = self.sim.od_int(self.node, 0x1A00, "B", 0)
        data = bytes(
            self.inputs[((self.od_u32(0x1A00, k) >> 8) & 0xFF) - 1] for k in range(1, n + 1)
        )
        self.node.network.send_message(cob & 0x7FF, data)
        # on the bus now (vcan delivers at once): this time orders it among the
        # SYNCs' receive times in sync.csv, whatever this simulator's own lag
        t_bus = time.time()
        self.rec.event(
            self.id, "tpdo", data=data.hex(), sync=self.sim.sync_no, t_bus=t_bus, why=why
        )

    def _on_rpdo(self, can_id: int, data: bytearray, timestamp: float) -> None:
        with self.sim.lock:
            if not self.operational:
                # CiA 301: PDOs only while operational. A frame delivered
                # before a reboot or an NMT command left it, whose callback
                # waited for the lock meanwhile, is not applied after
                return
            n = self.sim.od_int(self.node, 0x1600, "B", 0)
            if len(data) < n:
                return
            new = bytearray(self.outputs)
            for k in range(1, n + 1):
                sub = (self.od_u32(0x1600, k) >> 8) & 0xFF
                new[sub - 1] = data[k - 1]
            if new != self.outputs and not self.master_lost:
                self.outputs[:] = new
                for i in range(NBYTES):
                    self.node.data_store.setdefault(0x6200, {})[i + 1] = bytes([new[i]])
                # t_bus: the frame's bus time (a test orders it against the
                # SYNCs' when the emulated VM delivers frames out of order)
                self.rec.event(
                    self.id,
                    "outputs",
                    data=bytes(new).hex(),
                    sync=self.sim.sync_no,
                    t_bus=timestamp,
                )

    # ------------------------------------------------------------ the master's heartbeat
    def consumer(self, val: int) -> None:
        self._consumer_off()
        producer, ms = (val >> 16) & 0x7F, val & 0xFFFF
        if producer and ms:
            self.master = (producer, ms)
            self.master_lost = False
            self.node.network.subscribe(0x700 + producer, self._on_master_hb)

    def _consumer_off(self) -> None:
        if self.master is not None:
            self.node.network.unsubscribe(0x700 + self.master[0], self._on_master_hb)
        self.master = None
        self.master_seen = None

    def _on_master_hb(self, can_id: int, data: bytearray, timestamp: float) -> None:
        # never back: a stall of the simulator itself moved it on (DriveSim)
        self.master_seen = max(timestamp, self.master_seen or 0.0)
        self.master_lost = False

    def check_heartbeats(self, now: float) -> None:
        """The master's heartbeat overdue: every output off, EMCY 0x8130."""
        if self.master is None or self.master_seen is None or self.master_lost:
            return
        if now - self.master_seen > self.master[1] / 1000.0:
            self.master_lost = True
            self.outputs[:] = bytes(NBYTES)
            for i in range(NBYTES):
                self.node.data_store.setdefault(0x6200, {})[i + 1] = b"\x00"
            self.rec.event(self.id, "heartbeat_lost", producer=self.master[0])
            self.rec.event(self.id, "outputs", data=bytes(self.outputs).hex(), why="heartbeat")
            if self.present:
                self.node.emcy.send(0x8130, 0x11)

    # ------------------------------------------------------------ the probe
    def _set_input(self, b: int, k: int, v: int, why: str) -> bool:
        old = self.inputs[b - 1]
        self.inputs[b - 1] = (old | 1 << k) if v else (old & ~(1 << k) & 0xFF)
        if self.inputs[b - 1] != old:
            self._send_inputs(why)
            return True
        return False

    def follow(self, drive_id: int, actual: int, sync_no: int) -> None:
        """After drive drive_id moved at this SYNC: the probe's input from
        its position actual against the surface (a change goes out at once,
        in this SYNC's period, as a module reading a touch plate would)."""
        if self.probe is None or self.probe[2] != drive_id:
            return
        b, k, _, counts, below = self.probe
        touch = actual <= counts if below else actual >= counts
        if self._set_input(b, k, int(touch), f"probe {'on' if touch else 'off'}"):
            self.rec.event(
                self.id,
                "probe",
                on=touch,
                sync=sync_no,
                actual=actual,
                surface=counts,
                drive=drive_id,
            )

    def outputs_row(self) -> tuple[str, str]:
        return bytes(self.outputs).hex(), bytes(self.inputs).hex()

    # ------------------------------------------------------------ injections
    def inject(self, what: str, arg: str | None = None) -> None:
        self.rec.event(self.id, "inject", what=what, arg=arg)
        if self.inject_common(what, arg):
            return
        if what == "input":
            where, _, value = (arg or "").partition("=")
            byte, _, bit = where.partition(".")
            b, k, v = int(byte), int(bit), int(value)
            if not (1 <= b <= NBYTES and 0 <= k <= 7 and v in (0, 1)):
                raise ValueError(f"input '{arg}': expected BYTE.BIT=0|1, byte 1..8, bit 0..7")
            self._set_input(b, k, v, f"input {b}.{k}={v}")
        elif what == "probe":
            if arg == "off":
                self.probe = None
                return
            f = (arg or "").split(",")
            try:
                byte, _, bit = f[0].partition(".")
                b, k, node, counts = int(byte), int(bit), int(f[1]), int(f[2])
                below = {"below": True, "above": False}[f[3]]
            except (IndexError, KeyError, ValueError):
                raise ValueError(
                    f"probe '{arg}': expected BYTE.BIT,DRIVE,COUNTS,below|above"
                ) from None
            if not (1 <= b <= NBYTES and 0 <= k <= 7):
                raise ValueError(f"probe '{arg}': byte 1..8, bit 0..7")
            self.probe = (b, k, node, counts, below)
            d = self.sim.drives.get(node)
            if d is not None:
                self.follow(node, d.actual, self.sim.sync_no)
        elif what == "reboot":
            # a power cycle: every object to its default but the inputs (they
            # are physical), outputs off, no heartbeat consumed, boot-up sent;
            # reboot=PRODUCT: another module took its place (its product
            # code 0x1018:02 PRODUCT from then on), the inputs wired as before
            with self.sim.lock:
                ident = self.node.object_dictionary[0x1018]
                if arg and isinstance(ident, ODRecord):  # the new module's own identity
                    ident[2].default = ident[2].value = int(arg, 0) & 0xFFFFFFFF
                ds = self.node.data_store
                for k in list(ds):
                    if k != 0x6000:
                        del ds[k]
                self._consumer_off()
                self._error_reg()
                self.master_lost = False
                self.outputs[:] = bytes(NBYTES)
                self.rec.event(self.id, "outputs", data=bytes(self.outputs).hex(), why="reboot")
                self._boot("power cycle (injected)")
        elif what == "fault":
            code = 0 if arg == "off" else int(arg, 0) if arg else 0x5000
            with self.sim.lock:
                self.error_reg = 0x01 if code else 0
                self._error_reg()
            if self.present:
                self.node.emcy.send(code, self.error_reg)
            # on the bus now: orders it among the SYNCs' receive times (as a TPDO's)
            t_bus = time.time()
            self.rec.event(
                self.id, "emcy", code=f"0x{code:04X}", register=self.error_reg, t_bus=t_bus
            )
        else:
            raise ValueError(f"unknown injection '{what}' for the I/O module")

    def _error_reg(self) -> None:
        """0x1001 as the injected fault says (a reset's defaults would clear it)."""
        self.node.data_store.setdefault(0x1001, {})[0] = bytes([self.error_reg])

    def outputs_hex(self) -> str:
        return struct.pack(f"{NBYTES}B", *self.outputs).hex()
