"""The CAN bus, one way for every tool: python-can's can.Bus on SocketCAN.

open_bus() is what the drive simulator (through canopen's Network), the
listener's python-can path and the tests use. The listener's fast path (a raw
socket read with recvmmsg, for the software-emulated test VM) is in
mlipcan.sources; it sets the socket up the way python-can's socketcan
interface does."""

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import can


def open_bus(
    channel: str,
    fd: bool = False,
    receive_own_messages: bool = False,
    interface: str = "socketcan",
    **kw: Any,
) -> "can.BusABC":
    """A python-can bus on `channel` (e.g. vcan0). fd: CAN FD frames too.
    Raises RuntimeError naming the channel when it cannot be opened."""
    import can  # costs tens of seconds in the emulated VM: only when asked for

    try:
        return can.Bus(
            interface=interface,
            channel=channel,
            fd=fd,
            receive_own_messages=receive_own_messages,
            **kw,
        )
    except (OSError, can.CanError) as e:
        raise RuntimeError(f"cannot open {interface} {channel}: {e}") from e


def python_can_version() -> str:
    import can

    return can.__version__
