/*
 * keys.c - the keys of each section kind, in the order of keys.h's enums,
 * with how each value is read and whether it is required.
 */
#include "keys.h"

const struct keydef mlip_mc_keytab[N_KINDS][NKEYS] = {
    [K_TRAJ] = {{"COORDINATES", V_COORDS, 1},
                {"MAX_LINEAR_VELOCITY", V_POS, 1},
                {"MAX_ANGULAR_VELOCITY", V_POS, 0},
                {"CONTOUR_TOLERANCE", V_POS, 1},
                {"PERIOD", V_PERIOD, 0},
                {"LINEAR_UNITS", V_LUNITS, 0},
                {"ANGULAR_UNITS", V_AUNITS, 0},
                {"LOOKAHEAD", V_LOOKAHEAD, 0},
                {"JERK_PLAN", V_JPLAN, 0}},
    [K_AXIS] = {{"TYPE", V_TYPE, 0},
                {"MAX_VELOCITY", V_POS, 1},
                {"MAX_ACCELERATION", V_POS, 1},
                {"MIN_LIMIT", V_REAL, 0},
                {"MAX_LIMIT", V_REAL, 0},
                {"HOME", V_REAL, 0},
                {"CAN_NODE", V_NODE, 0},
                {"COUNTS_PER_UNIT", V_POS, 0},
                {"LIMIT_NEG", V_IOBIT, 0},
                {"LIMIT_POS", V_IOBIT, 0},
                {"HOME_SWITCH", V_IOBIT, 0},
                {"HOME_METHOD", V_METHOD, 0},
                {"HOME_SEARCH_VEL", V_POS, 0},
                {"HOME_LATCH_VEL", V_POS, 0},
                {"HOME_ACCEL", V_POS, 0},
                {"HOME_OFFSET", V_REAL, 0},
                {"HOME_SEQUENCE", V_SEQUENCE, 0},
                {"HOME_TIMEOUT", V_POS, 0},
                {"MAX_JERK", V_POS, 0},
                {"LIMIT_INPUTS", V_LINPUTS, 0}},
    [K_CAN] = {{"PROFILE", V_PROFILE, 0},
               {"BITRATE", V_BITRATE, 0},
               {"DATA_BITRATE", V_DBITRATE, 0},
               {"SYNC_ID", V_ID, 0},
               {"RPDO_BASE", V_ID, 0},
               {"PACKED_BASE", V_ID, 0},
               {"FD_ID", V_ID, 0},
               {"STATUS_ID", V_ID, 0}},
    [K_DRIVES] = {{"ENABLE", V_BOOL, 0},
                  {"MASTER_NODE", V_NODE, 0},
                  {"HEARTBEAT_MS", V_MS, 0},
                  {"HEARTBEAT_TIMEOUT_MS", V_MS, 0},
                  {"FOLLOWING_ERROR", V_POS, 0},
                  {"SDO_TIMEOUT_MS", V_MS, 0},
                  {"BOOT_TIMEOUT_MS", V_MS, 0},
                  {"STATE_TIMEOUT_MS", V_MS, 0},
                  {"HOMING_REQUIRED", V_BOOL, 0}},
    [K_SPINDLE] = {{"TYPE", V_IO, 0},
                   {"MIN_RPM", V_RPM, 0},
                   {"MAX_RPM", V_RPM, 0},
                   {"NODE", V_NODE, 0},
                   {"COUNTS_PER_REV", V_POS, 0},
                   {"ACCELERATION", V_POS, 0},
                   {"AT_SPEED_BAND", V_RPM, 0},
                   {"AT_SPEED_TIMEOUT", V_POS, 0},
                   {"BAND_TIME", V_POS, 0}},
    [K_TOOL] = {{"CHANGE", V_IO, 0},
                {"CHANGE_X", V_REAL, 0},
                {"CHANGE_Y", V_REAL, 0},
                {"CHANGE_Z", V_REAL, 0},
                {"CHANGE_A", V_REAL, 0},
                {"CHANGE_B", V_REAL, 0},
                {"CHANGE_C", V_REAL, 0}},
    [K_COOLANT] = {{"TYPE", V_COOLANT, 0}, {"MIST", V_OUTBIT, 0}, {"FLOOD", V_OUTBIT, 0}},
    [K_IO] = {{"NODE", V_NODE, 0},
              {"ESTOP", V_IOBIT, 0},
              {"HOLD", V_IOBIT, 0},
              {"CYCLE_START", V_IOBIT, 0},
              {"PROBE", V_IOBIT, 0},
              {"OUTPUT_0", V_OUTBIT, 0},
              {"OUTPUT_1", V_OUTBIT, 0},
              {"OUTPUT_2", V_OUTBIT, 0},
              {"OUTPUT_3", V_OUTBIT, 0},
              {"OUTPUT_4", V_OUTBIT, 0},
              {"OUTPUT_5", V_OUTBIT, 0},
              {"OUTPUT_6", V_OUTBIT, 0},
              {"OUTPUT_7", V_OUTBIT, 0}},
    [K_PROBE] = {{"SOURCE", V_PSOURCE, 0}},
};

/* "TRAJ", "CAN", "AXIS_X", ... */
void mlip_mc_secname(struct mlip_tb *b, int sec)
{
	if (sec == SEC_TRAJ) {
		mlip_tb_puts(b, "TRAJ");
	} else if (sec == SEC_CAN) {
		mlip_tb_puts(b, "CAN");
	} else if (sec == SEC_DRIVES) {
		mlip_tb_puts(b, "DRIVES");
	} else if (sec == SEC_SPINDLE) {
		mlip_tb_puts(b, "SPINDLE");
	} else if (sec == SEC_TOOL) {
		mlip_tb_puts(b, "TOOL");
	} else if (sec == SEC_COOLANT) {
		mlip_tb_puts(b, "COOLANT");
	} else if (sec == SEC_IO) {
		mlip_tb_puts(b, "IO");
	} else if (sec == SEC_PROBE) {
		mlip_tb_puts(b, "PROBE");
	} else {
		mlip_tb_puts(b, "AXIS_");
		mlip_tb_putc(b, AXIS_LETTERS[sec - SEC_AXIS0]);
	}
}
