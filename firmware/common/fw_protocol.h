/* Constants of docs/radio_protocol.md and firmware/INTERFACE.md that the
 * firmware and the C++ side (core/radio) must agree on.
 * firmware_protocol_test (tests/firmware) compiles this header on the host
 * and compares every value with core/radio's, so a change on one side that
 * is not made on the other fails `make test`. Plain C11, no AVR headers. */
#ifndef ROOMFIX_FIRMWARE_COMMON_FW_PROTOCOL_H_
#define ROOMFIX_FIRMWARE_COMMON_FW_PROTOCOL_H_

/* Firmware version, sent in the device status payload. */
#define FW_VERSION 1

/* roomfix payload (docs/radio_protocol.md, section 2). */
#define FW_PAYLOAD_VERSION 1
#define FW_TYPE_FIRING 0x01
#define FW_TYPE_RANGE_REPORT 0x02
#define FW_TYPE_DEVICE_STATUS 0x03
#define FW_FIRING_BYTES 10
#define FW_REPORT_BYTES 14
#define FW_STATUS_BYTES 8
#define FW_FLAG_WEAK_ECHO 0x01
#define FW_FLAG_NO_ECHO 0x02
#define FW_NO_TEMPERATURE 0x8000u

/* XBee API frames (section 1). */
#define FW_XBEE_START 0x7E
#define FW_XBEE_ESCAPE 0x7D
#define FW_XBEE_XON 0x11
#define FW_XBEE_XOFF 0x13
#define FW_XBEE_ESCAPE_XOR 0x20
#define FW_XBEE_TX64 0x00
#define FW_XBEE_TX16 0x01
#define FW_XBEE_RX64 0x80
#define FW_XBEE_RX16 0x81
#define FW_XBEE_ZB_RX 0x90
/* RF data offset in the frame data (type byte included) of each receive
 * frame: 0x80 type, 64-bit source, RSSI, options; 0x81 type, 16-bit source,
 * RSSI, options; 0x90 type, 64-bit source, 16-bit source, options. */
#define FW_XBEE_RX64_HEADER 11
#define FW_XBEE_RX16_HEADER 5
#define FW_XBEE_ZB_RX_HEADER 12
/* The longest frame data the firmware keeps; longer frames are skipped
 * (the bridge's limit is 128; a device needs only the announcement). */
#define FW_XBEE_MAX_DATA 48

/* Device faults (device status payload, byte 3). */
#define FW_FAULT_NONE 0
#define FW_FAULT_CONFIG_MISSING 1
#define FW_FAULT_CONFIG_CRC 2
#define FW_FAULT_CONFIG_VERSION 3
#define FW_FAULT_CONFIG_INVALID 4
#define FW_FAULT_SELF_TEST 5

/* EEPROM configuration (firmware/INTERFACE.md). */
#define FW_CONFIG_MAGIC0 0x52 /* 'R' */
#define FW_CONFIG_MAGIC1 0x46 /* 'F' */
#define FW_CONFIG_LAYOUT_VERSION 1
#define FW_CONFIG_BYTES 72
#define FW_ROLE_BEACON 1
#define FW_ROLE_RECEIVER 2
#define FW_MAX_SLOTS 12
#define FW_MAX_FIRE_DELAY_US 4000u
#define FW_MIN_FIRE_DELAY_US 100u
#define FW_MAX_WINDOW_US 200000ul
#define FW_MAX_BURST_CYCLES 64

/* Clock: Timer1 at clk/1. */
#define FW_CPU_HZ 16000000ul
#define FW_TICKS_PER_US 16u
#define FW_UART_BAUD 250000ul
/* Ticks per UART byte: 10 bits (start, 8 data, stop) at FW_UART_BAUD. */
#define FW_TICKS_PER_UART_BYTE (10u * (FW_CPU_HZ / FW_UART_BAUD))
/* Half a period of the 40 kHz carrier, in ticks. */
#define FW_CARRIER_HZ 40000ul
#define FW_HALF_CARRIER_TICKS (FW_CPU_HZ / (2u * FW_CARRIER_HZ))

#endif /* ROOMFIX_FIRMWARE_COMMON_FW_PROTOCOL_H_ */
