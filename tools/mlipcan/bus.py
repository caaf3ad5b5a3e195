"""The CAN bus, one way for every tool: python-can's can.Bus on SocketCAN.

open_bus() is what the drive simulator (through canopen's Network), the
listener's python-can path and the tests use. The listener's fast path (a raw
socket read with recvmmsg, for the software-emulated test VM) is in
mlipcan.sources; it sets the socket up the way python-can's socketcan
interface does."""


def open_bus(channel, fd=False, receive_own_messages=False, interface="socketcan", **kw):
    """A python-can bus on `channel` (e.g. vcan0). fd: CAN FD frames too.
    Raises RuntimeError naming the channel when it cannot be opened."""
    import can  # costs tens of seconds in the emulated VM: only when asked for

    try:
        return can.Bus(interface=interface, channel=channel, fd=fd,
                       receive_own_messages=receive_own_messages, **kw)
    except (OSError, can.CanError) as e:
        raise RuntimeError(f"cannot open {interface} {channel}: {e}")


def python_can_version():
    import can

    return can.__version__
