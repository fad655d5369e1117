/*
 * The PMSIS RAM driver (gap_sdk pmsis_bsp bsp/ram.h, bsp/ram/hyperram.h)
 * on the µDMA's HyperRAM channel (udma_regs.h). A transfer is queued by
 * staging its L2 address, L3 address and size, then writing CMD; the
 * channel runs transfers in queue order while the cores go on. A task's
 * completion is its ticket, the ISSUED count after its CMD: it is done
 * when DONE has reached it (pi_task_wait_on polls DONE; the ISS skips
 * the idle polls).
 */
#include "pmsis_internal.h"
#include "udma_regs.h"

/* The state of the opened device: the one HyperRAM. */
static struct {
    int opened;
} hyper;

void pi_hyperram_conf_init(struct pi_hyperram_conf *conf)
{
    conf->ram.api = NULL;
    conf->hyper_itf = 0;
    conf->hyper_cs = 0;
    conf->ram_start = 0;
    conf->ram_size = UDMA_HYPER_RAM_BYTES;
    conf->skip_pads_config = 0;
}

int32_t pi_ram_open(struct pi_device *device)
{
    if (!device || hyper.opened)
        return -1;
    hyper.opened = 1;
    device->data = &hyper;
    return 0;
}

void pi_ram_close(struct pi_device *device)
{
    if (device && device->data == &hyper) {
        hyper.opened = 0;
        device->data = NULL;
    }
}

/* Queues one transfer; returns its ticket. */
static uint32_t enqueue(struct pi_device *device, uint32_t l3, void *data, uint32_t size,
                        uint32_t cmd)
{
    if (!device || device->data != &hyper)
        __pi_fatal("pi_ram: the device is not open");
    udma_hyper_write(UDMA_HYPER_L2_ADDR, (uint32_t)data);
    udma_hyper_write(UDMA_HYPER_L3_ADDR, l3);
    udma_hyper_write(UDMA_HYPER_SIZE, size);
    udma_hyper_write(UDMA_HYPER_CMD, cmd);
    return udma_hyper_read(UDMA_HYPER_ISSUED);
}

static void wait_ticket(uint32_t ticket)
{
    while (!udma_hyper_done(ticket))
        ;
}

void pi_ram_read(struct pi_device *device, uint32_t pi_ram_addr, void *data, uint32_t size)
{
    wait_ticket(enqueue(device, pi_ram_addr, data, size, UDMA_HYPER_CMD_READ));
}

void pi_ram_write(struct pi_device *device, uint32_t pi_ram_addr, void *data, uint32_t size)
{
    wait_ticket(enqueue(device, pi_ram_addr, data, size, UDMA_HYPER_CMD_WRITE));
}

void pi_ram_read_async(struct pi_device *device, uint32_t pi_ram_addr, void *data,
                       uint32_t size, pi_task_t *task)
{
    task->done = 0;
    task->next = NULL;
    task->ram_ticket = enqueue(device, pi_ram_addr, data, size, UDMA_HYPER_CMD_READ);
}

void pi_ram_write_async(struct pi_device *device, uint32_t pi_ram_addr, void *data,
                        uint32_t size, pi_task_t *task)
{
    task->done = 0;
    task->next = NULL;
    task->ram_ticket = enqueue(device, pi_ram_addr, data, size, UDMA_HYPER_CMD_WRITE);
}

void pi_ram_copy(struct pi_device *device, uint32_t pi_ram_addr, void *data, uint32_t size,
                 int ext2loc)
{
    if (ext2loc)
        pi_ram_read(device, pi_ram_addr, data, size);
    else
        pi_ram_write(device, pi_ram_addr, data, size);
}

void pi_ram_copy_async(struct pi_device *device, uint32_t pi_ram_addr, void *data,
                       uint32_t size, int ext2loc, pi_task_t *task)
{
    if (ext2loc)
        pi_ram_read_async(device, pi_ram_addr, data, size, task);
    else
        pi_ram_write_async(device, pi_ram_addr, data, size, task);
}
