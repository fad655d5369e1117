/*
 * The cluster DMA (MCHAN) through this core's staging registers
 * (docs/CLUSTER.md, DMA). Each command gets the queue's id; its completion
 * sets event bit 8 of the core that enqueued it, which pi_cl_dma_cmd_wait
 * sleeps on.
 */
#include "pmsis_internal.h"

static uint32_t hw_dir(pi_cl_dma_dir_e dir)
{
    return dir == PI_CL_DMA_DIR_LOC2EXT ? CL_DMA_CMD_LOC2EXT : 0;
}

/* Enqueues one command (sleeps while 16 are queued); returns its id. */
static int enqueue(uint32_t ext, uint32_t loc, uint32_t size, uint32_t stride, uint32_t length,
                   uint32_t cmd)
{
    cl_write(CL_DMA_BASE, CL_DMA_EXT, ext);
    cl_write(CL_DMA_BASE, CL_DMA_LOC, loc);
    cl_write(CL_DMA_BASE, CL_DMA_SIZE, size);
    if (cmd & CL_DMA_CMD_2D) {
        cl_write(CL_DMA_BASE, CL_DMA_STRIDE, stride);
        cl_write(CL_DMA_BASE, CL_DMA_LENGTH, length);
    }
    cl_write(CL_DMA_BASE, CL_DMA_CMD, cmd);
    return (int)cl_read(CL_DMA_BASE, CL_DMA_ID);
}

static void wait_id(uint32_t id)
{
    /* A completion before the wait leaves bit 8 in the buffer, so the
     * EVT_WAIT_CLR returns at once and the loop looks again. */
    while (cl_read(CL_DMA_BASE, CL_DMA_STATUS) & (1u << id))
        (void)cl_read(CL_EU_BASE, CL_EU_EVT_WAIT_CLR);
}

void pi_cl_dma_cmd(uint32_t ext, uint32_t loc, uint32_t size, pi_cl_dma_dir_e dir,
                   pi_cl_dma_cmd_t *cmd)
{
    cmd->id = enqueue(ext, loc, size, 0, 0, hw_dir(dir));
}

void pi_cl_dma_cmd_2d(uint32_t ext, uint32_t loc, uint32_t size, uint32_t stride,
                      uint32_t length, pi_cl_dma_dir_e dir, pi_cl_dma_cmd_t *cmd)
{
    cmd->id = enqueue(ext, loc, size, stride, length, hw_dir(dir) | CL_DMA_CMD_2D);
}

void pi_cl_dma_cmd_wait(pi_cl_dma_cmd_t *cmd)
{
    wait_id((uint32_t)cmd->id);
}

void pi_cl_dma_memcpy(pi_cl_dma_copy_t *copy)
{
    copy->id = (uint32_t)enqueue(copy->ext, copy->loc, copy->size, 0, 0, hw_dir(copy->dir));
}

void pi_cl_dma_memcpy_2d(pi_cl_dma_copy_2d_t *copy)
{
    copy->id = (uint32_t)enqueue(copy->ext, copy->loc, copy->size, copy->stride, copy->length,
                                 hw_dir(copy->dir) | CL_DMA_CMD_2D);
}

void pi_cl_dma_wait(void *copy)
{
    wait_id(((pi_cl_dma_copy_t *)copy)->id);
}
