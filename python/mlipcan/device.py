"""What the simulated CANopen devices on the test bus share (CiA 301): the
node (canopen's LocalNode, every SDO download recorded, accepted or
refused), power on and off the bus with their own NMT handler, the boot-up,
the PDO COB-ID rule, and the injections every device takes (heartbeat off
or on, absent, present). drive.py's CiA 402 drives and io401.py's CiA 401
I/O modules are devices with their profile on top."""

from typing import TYPE_CHECKING, Any

from canopen.objectdictionary import ODRecord, ODVariable
from canopen.sdo.exceptions import SdoAbortedError

import canopen
from canopen import objectdictionary as odm

from . import cia402 as P

if TYPE_CHECKING:
    from .drive import DriveSim, Recorder

VENDOR_ID = 0x00000000  # none: a simulation
PRODUCT_CODE = 0x4D4C4950  # "MLIP"
PDO_INVALID = 0x80000000
U8, U32 = odm.UNSIGNED8, odm.UNSIGNED32


# ------------------------------------------------------------ object dictionary
def od_var(
    name: str,
    index: int,
    sub: int,
    dtype: int,
    access: str,
    default: int,
    mappable: bool = False,
    desc: str = "",
) -> ODVariable:
    v = ODVariable(name, index, sub)
    v.data_type, v.access_type, v.default, v.value = dtype, access, default, default
    v.pdo_mappable = mappable
    v.description = desc
    return v


def od_record(
    od: odm.ObjectDictionary, name: str, index: int, members: list[tuple[str, int, str, int]]
) -> None:
    """A record object: sub 0 the highest sub-index, then (name, type, access, default)."""
    r = ODRecord(name, index)
    r.add_member(od_var("Highest sub-index supported", index, 0, U8, "ro", len(members)))
    for i, (mname, dtype, access, default) in enumerate(members, 1):
        r.add_member(od_var(mname, index, i, dtype, access, default))
    od.add_object(r)


def new_od(node_id: int, vendor_name: str, product_name: str) -> odm.ObjectDictionary:
    """An empty object dictionary with the device's information."""
    od = odm.ObjectDictionary()
    od.node_id = node_id
    od.device_information.vendor_name = vendor_name
    od.device_information.product_name = product_name
    od.device_information.vendor_number = VENDOR_ID
    od.device_information.product_number = PRODUCT_CODE
    return od


def od_identity(od: odm.ObjectDictionary, node_id: int) -> None:
    """The identity object 0x1018: vendor, product, revision, serial = node id."""
    od_record(
        od,
        "Identity object",
        0x1018,
        [
            ("Vendor-ID", U32, "ro", VENDOR_ID),
            ("Product code", U32, "ro", PRODUCT_CODE),
            ("Revision number", U32, "ro", 0x00010000),
            ("Serial number", U32, "ro", node_id),
        ],
    )


class SimNode(canopen.LocalNode):
    """canopen's LocalNode with every SDO download recorded, accepted or not."""

    def __init__(self, dev: "SimDevice", node_id: int, od: odm.ObjectDictionary) -> None:
        super().__init__(node_id, od)
        self.dev = dev

    def set_data(
        self, index: int, subindex: int, data: bytes, check_writable: bool = False
    ) -> None:
        if not check_writable:  # the device's own writes (its state), not an SDO download
            super().set_data(index, subindex, data, check_writable)
            return
        d = self.dev

        def record(**kw: Any) -> None:
            where = {"index": f"0x{index:04X}", "sub": subindex, "data": bytes(data).hex()}
            d.rec.event(d.id, "sdo_write", **where, **kw)

        try:
            d.check_write(index, subindex, data)
            with d.sim.lock:
                super().set_data(index, subindex, data, check_writable)
        except SdoAbortedError as e:
            record(abort=f"0x{e.code:08X}", meaning=P.ABORT.get(e.code, "?"))
            raise
        d.written(index, subindex, data)
        record(value=d.value_of(index, subindex))


class SimDevice:
    """One device on the simulator's bus (DriveSim): its node, whether it is
    on the bus, whether its heartbeat is stopped (injected)."""

    node: SimNode

    def __init__(self, sim: "DriveSim", node_id: int) -> None:
        self.sim = sim
        self.rec: Recorder = sim.rec
        self.id = node_id
        self.present = False
        self.hb_stopped = False

    # ------------------------------------------------------------ SDO
    def check_write(self, index: int, sub: int, data: bytes) -> None:
        """An SDO download before canopen takes it: raise SdoAbortedError to refuse."""

    def written(self, index: int, sub: int, data: bytes) -> None:
        """An SDO download stored: its side effects."""

    def value_of(self, index: int, sub: int) -> Any:
        try:
            obj = self.node._find_object(index, sub)  # type: ignore[no-untyped-call]
            return obj.decode_raw(self.node.data_store[index][sub])
        except Exception:
            return None

    def od_u32(self, index: int, sub: int = 0) -> int:
        return self.sim.od_u32(self.node, index, sub)

    def check_cob_id(self, index: int, val: int) -> None:
        """CiA 301: a PDO's COB-ID (0x1400:1, 0x1800:1) changes only while
        the PDO is invalid."""
        old = self.od_u32(index, 1)
        if not old & PDO_INVALID and not val & PDO_INVALID and (old ^ val) & 0x7FF:
            raise SdoAbortedError(0x06090030)

    # ------------------------------------------------------------ bus
    def attach(self, network: canopen.Network) -> None:
        """Power up on the bus: boot-up message, pre-operational, heartbeat."""
        network.add_node(self.node)
        # our NMT handler instead of canopen's: boot-up and pre-operational
        # again after a reset, and the PDOs on entering operational
        network.unsubscribe(0, self.node.nmt.on_command)
        network.subscribe(0, self._on_nmt)
        self._on_bus(network)
        self.present = True
        self._boot("power on")

    def detach(self) -> None:
        """Gone from the bus (injected): no SDO answers, no heartbeat, no PDOs."""
        n = self.node
        net = n.network
        n.nmt.stop_heartbeat()
        self._pdo_off()
        net.unsubscribe(0, self._on_nmt)
        self._off_bus(net)
        net.subscribe(0, n.nmt.on_command)  # remove_network() unsubscribes it
        del net[self.id]  # remove_network(): the SDO server stops answering
        self.present = False
        self.rec.event(self.id, "absent")

    def _on_bus(self, network: canopen.Network) -> None:
        """Attaching: what the device listens to besides NMT."""

    def _off_bus(self, network: canopen.Network) -> None:
        """Detaching: no longer listening to it."""

    def _boot(self, why: str) -> None:
        """INITIALISING -> boot-up message -> PRE-OPERATIONAL (CiA 301)."""
        nmt = self.node.nmt
        nmt.stop_heartbeat()
        self._pdo_off()
        nmt.send_command(P.NMT_RESET_COMM)  # canopen: state 0 and the boot-up frame
        self.rec.event(self.id, "nmt", to="INITIALISING", why=why)
        nmt.send_command(P.NMT_PREOP)  # and the heartbeat producer (0x1017)
        if self.hb_stopped:
            nmt.stop_heartbeat()
        self.rec.event(self.id, "nmt", to="PRE-OPERATIONAL", why="boot-up sent")

    def _for_me(self, data: bytearray) -> bool:
        """An NMT command frame addressed to this node (or all), while on the bus."""
        return len(data) == 2 and data[1] in (0, self.id) and self.present

    def _on_nmt(self, can_id: int, data: bytearray, timestamp: float) -> None:
        raise NotImplementedError

    def _pdo_off(self) -> None:
        raise NotImplementedError

    # ------------------------------------------------------------ injections
    def inject_common(self, what: str, arg: str | None) -> bool:
        """The injections every device takes: heartbeat=off|on, absent,
        present; False for another one."""
        if what == "heartbeat":
            self.hb_stopped = arg == "off"
            if self.present:
                if self.hb_stopped:
                    self.node.nmt.stop_heartbeat()
                else:
                    self.node.nmt.start_heartbeat(self.sim.od_int(self.node, 0x1017, "<H"))
        elif what == "absent":
            if self.present:
                self.detach()
        elif what == "present":
            if not self.present:
                self.attach(self.sim.network)
        else:
            return False
        return True
