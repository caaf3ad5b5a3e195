"""CiA 402 (drive profile) and CiA 301 (CANopen) numbers the simulated drives
and the tests share. Standard library only.

The power state machine (CiA 402 part 2, figure "state machine"): states,
their statusword patterns (mask, value), and the controlword commands."""

# states, by their statusword pattern (bits 0-3, 5, 6)
NOT_READY = "not ready to switch on"
SWITCH_ON_DISABLED = "switch on disabled"
READY = "ready to switch on"
SWITCHED_ON = "switched on"
OPERATION_ENABLED = "operation enabled"
QUICK_STOP = "quick stop active"
FAULT_REACTION = "fault reaction active"
FAULT = "fault"

# state -> (statusword mask, value)
SW_PATTERN = {
    NOT_READY: (0x4F, 0x00),
    SWITCH_ON_DISABLED: (0x4F, 0x40),
    READY: (0x6F, 0x21),
    SWITCHED_ON: (0x6F, 0x23),
    OPERATION_ENABLED: (0x6F, 0x27),
    QUICK_STOP: (0x6F, 0x07),
    FAULT_REACTION: (0x4F, 0x0F),
    FAULT: (0x4F, 0x08),
}

# statusword bits beyond the state pattern
SW_VOLTAGE_ENABLED = 1 << 4
SW_QUICK_STOP = 1 << 5  # 1: quick stop NOT active
SW_WARNING = 1 << 7
SW_REMOTE = 1 << 9
SW_TARGET_REACHED = 1 << 10
SW_CSP_FOLLOWING = 1 << 12  # CSP: the drive follows the target position
SW_FOLLOWING_ERROR = 1 << 13

# controlword commands (CiA 402 table "device control commands"): (mask, value)
CW_SHUTDOWN = (0x87, 0x06)
CW_SWITCH_ON = (0x8F, 0x07)  # also "disable operation" from operation enabled
CW_ENABLE_OPERATION = (0x8F, 0x0F)  # switch on + enable operation
CW_DISABLE_VOLTAGE = (0x82, 0x00)
CW_QUICK_STOP = (0x86, 0x02)
CW_FAULT_RESET = 0x80  # rising edge of bit 7

# the values a master writes
CONTROLWORD = {
    "shutdown": 0x06,
    "switch on": 0x07,
    "enable operation": 0x0F,
    "disable operation": 0x07,
    "disable voltage": 0x00,
    "quick stop": 0x02,
    "fault reset": 0x80,
}

MODE_CSP = 8  # 0x6060 modes of operation: cyclic synchronous position


def state_of(statusword: int) -> str | None:
    """The power state a statusword shows (None: no valid pattern)."""
    for name, (mask, value) in SW_PATTERN.items():
        if statusword & mask == value:
            return name
    return None


def command_of(controlword: int) -> str | None:
    """The device control command of a controlword (None: no command, e.g.
    bit 7 alone is the fault reset edge, judged by the caller)."""
    for name, (mask, value) in (
        ("disable voltage", CW_DISABLE_VOLTAGE),
        ("quick stop", CW_QUICK_STOP),
        ("shutdown", CW_SHUTDOWN),
        ("switch on", CW_SWITCH_ON),
        ("enable operation", CW_ENABLE_OPERATION),
    ):
        if controlword & mask == value:
            return name
    return None


# CiA 301 SDO abort codes (table "SDO abort codes") the drives give
ABORT = {
    0x05030000: "toggle bit not alternated",
    0x05040001: "client/server command specifier not valid or unknown",
    0x06010000: "unsupported access to an object",
    0x06010001: "attempt to read a write only object",
    0x06010002: "attempt to write a read only object",
    0x06020000: "object does not exist in the object dictionary",
    0x06040041: "object cannot be mapped to the PDO",
    0x06040042: "the number and length of the objects to be mapped would exceed the PDO length",
    0x06040043: "general parameter incompatibility reason",
    0x06070010: "data type does not match, length of service parameter does not match",
    0x06090011: "sub-index does not exist",
    0x06090030: "invalid value for parameter (download only)",
    0x06090031: "value of parameter written too high (download only)",
    0x06090032: "value of parameter written too low (download only)",
    0x08000000: "general error",
    0x08000020: "data cannot be transferred or stored to the application",
    0x08000022: "data cannot be transferred or stored to the application because of the "
    "present device state",
}

# CiA 301 / CiA 402 emergency error codes the drives send
EMCY = {
    0x0000: "error reset or no error",
    0x2310: "continuous over-current (device output side)",
    0x3210: "DC link over-voltage",
    0x5530: "hardware: data storage (non-volatile memory)",
    0x7500: "communication (additional module)",
    0x8130: "life guard error or heartbeat error",
    0x8611: "following error (positioning controller)",
}

# NMT (CiA 301): command specifiers and the states a heartbeat reports
NMT_START, NMT_STOP, NMT_PREOP, NMT_RESET_NODE, NMT_RESET_COMM = 0x01, 0x02, 0x80, 0x81, 0x82
HB_STATE = {0x00: "boot-up", 0x04: "stopped", 0x05: "operational", 0x7F: "pre-operational"}

# short names of the objects a master writes at bring-up (for reports)
OBJECT = {
    0x1005: "COB-ID SYNC",
    0x1016: "consumer heartbeat",
    0x1017: "producer heartbeat",
    0x1400: "RPDO1 comm",
    0x1600: "RPDO1 map",
    0x1800: "TPDO1 comm",
    0x1A00: "TPDO1 map",
    0x6040: "controlword (hex)",
    0x6060: "modes of operation",
    0x6065: "following error window",
    0x607A: "target position",
    0x60C2: "interpolation period",
}
