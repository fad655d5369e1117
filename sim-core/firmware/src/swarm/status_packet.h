/*
 * The STATUS packet of seed 003 §6.7, serialised byte by byte in little
 * endian (no packed structs: §6.10's unaligned-pointer fault cannot happen).
 *
 * Header, 8 bytes (Code Block 6.3):
 *   0     sourceId       the sender's identifier (§6.2)
 *   1     type           SWARM_PACKET_TYPE_STATUS (§6.1)
 *   2     seqNr          the sender's sequence number (§6.3)
 *   3..6  tx             low 32 bits of the sender's DW1000 stamp of its
 *                        PREVIOUS transmission (packet seqNr - 1)
 *   7     payloadLength  bits 0-6: number of entries; bit 7: tx is valid
 *
 * Entries, 8 bytes each (Code Block 6.4), one per neighbour:
 *   0     id             the neighbour
 *   1     seqNr          the sequence number of the neighbour's packet
 *                        whose reception time follows
 *   2..5  rx             low 32 bits of the sender's stamp of that reception
 *   6..7  tof            the sender's last TOF to that neighbour, ticks
 *                        (0: none), §5.3.1
 *
 * Deviation from the seed (docs/SWARM_FIRMWARE.md §2): the thesis filled
 * `tx` with the stamp of the packet itself, which needs the DW1000's
 * delayed transmission; our radio reports a stamp only once a frame has
 * left (TX_DONE), so a packet carries the stamp of the sender's previous
 * one, and each entry pairs the reception it reports with that previous
 * transmission. The entry's 4-byte `tx` echo becomes a 1-byte sequence
 * number (the receiver keeps its own recent transmit stamps), so an entry
 * is 8 bytes, not 11, and 14 neighbours fit in 127 bytes instead of 10.
 */
#ifndef SWARM_STATUS_PACKET_H
#define SWARM_STATUS_PACKET_H

#include <stddef.h>
#include <stdint.h>

/* §6.1: common to every STATUS packet. The seed gives no value; any byte
 * the other DW1000 applications in the room do not use works (0xA3 reads
 * "seed 003"). */
#define SWARM_PACKET_TYPE_STATUS 0xA3
#define SWARM_HEADER_BYTES 8
#define SWARM_ENTRY_BYTES 8
/* IEEE 802.15.4-2011 / DW1000 standard frame: at most 127 bytes (§6.7). */
#define SWARM_MAX_FRAME 127
#define SWARM_MAX_ENTRIES ((SWARM_MAX_FRAME - SWARM_HEADER_BYTES) / SWARM_ENTRY_BYTES)
#define SWARM_TX_VALID 0x80

typedef struct {
    uint8_t id;
    uint8_t seq;
    uint32_t rx;
    uint16_t tof;
} swarm_entry_t;

typedef struct {
    uint8_t source_id;
    uint8_t seq;
    uint8_t tx_valid;
    uint8_t count;
    uint32_t tx;
    swarm_entry_t entry[SWARM_MAX_ENTRIES];
} swarm_status_t;

/* Bytes of a packet with `count` entries. */
static inline size_t swarm_status_size(unsigned count)
{
    return SWARM_HEADER_BYTES + (size_t)count * SWARM_ENTRY_BYTES;
}

/* Serialise into buf; returns the length, or 0 when it does not fit in
 * `cap` or count > SWARM_MAX_ENTRIES. */
size_t swarm_status_write(const swarm_status_t *p, uint8_t *buf, size_t cap);

enum {
    SWARM_PARSE_OK = 0,
    SWARM_PARSE_SHORT = -1,     /* shorter than a header */
    SWARM_PARSE_NOT_STATUS = -2, /* another application's frame (§6.1) */
    SWARM_PARSE_BAD_LENGTH = -3, /* length does not match payloadLength */
};

/* Parse a received frame; SWARM_PARSE_OK or a negative reason. */
int swarm_status_read(swarm_status_t *p, const uint8_t *buf, size_t len);

#endif
