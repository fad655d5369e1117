/* The STATUS packet of seed 003 §6.7: see status_packet.h. */
#include "status_packet.h"

static void put32(uint8_t *b, uint32_t v)
{
    b[0] = (uint8_t)v;
    b[1] = (uint8_t)(v >> 8);
    b[2] = (uint8_t)(v >> 16);
    b[3] = (uint8_t)(v >> 24);
}

static uint32_t get32(const uint8_t *b)
{
    return (uint32_t)b[0] | (uint32_t)b[1] << 8 | (uint32_t)b[2] << 16 | (uint32_t)b[3] << 24;
}

size_t swarm_status_write(const swarm_status_t *p, uint8_t *buf, size_t cap)
{
    if (p->count > SWARM_MAX_ENTRIES)
        return 0;
    size_t len = swarm_status_size(p->count);
    if (len > cap)
        return 0;
    buf[0] = p->source_id;
    buf[1] = SWARM_PACKET_TYPE_STATUS;
    buf[2] = p->seq;
    put32(buf + 3, p->tx);
    buf[7] = (uint8_t)(p->count | (p->tx_valid ? SWARM_TX_VALID : 0));
    uint8_t *e = buf + SWARM_HEADER_BYTES;
    for (unsigned i = 0; i < p->count; i++, e += SWARM_ENTRY_BYTES) {
        const swarm_entry_t *s = &p->entry[i];
        e[0] = s->id;
        e[1] = s->seq;
        put32(e + 2, s->rx);
        e[6] = (uint8_t)s->tof;
        e[7] = (uint8_t)(s->tof >> 8);
    }
    return len;
}

int swarm_status_read(swarm_status_t *p, const uint8_t *buf, size_t len)
{
    if (len < SWARM_HEADER_BYTES)
        return SWARM_PARSE_SHORT;
    if (buf[1] != SWARM_PACKET_TYPE_STATUS)
        return SWARM_PARSE_NOT_STATUS;
    unsigned count = buf[7] & ~SWARM_TX_VALID & 0xff;
    if (count > SWARM_MAX_ENTRIES || len != swarm_status_size(count))
        return SWARM_PARSE_BAD_LENGTH;
    p->source_id = buf[0];
    p->seq = buf[2];
    p->tx = get32(buf + 3);
    p->tx_valid = (buf[7] & SWARM_TX_VALID) != 0;
    p->count = (uint8_t)count;
    const uint8_t *e = buf + SWARM_HEADER_BYTES;
    for (unsigned i = 0; i < count; i++, e += SWARM_ENTRY_BYTES) {
        swarm_entry_t *s = &p->entry[i];
        s->id = e[0];
        s->seq = e[1];
        s->rx = get32(e + 2);
        s->tof = (uint16_t)(e[6] | e[7] << 8);
    }
    return SWARM_PARSE_OK;
}
