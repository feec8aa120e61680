/*
 * A fake libladybug for rigd's tests: the Ladybug SDK's function names over our own minimal structs
 * (fake_sdk/ladybug.h). It serves RAW8 frames (six Bayer images, pixel value = 40 * camera + frame) or,
 * when a frame block is loaded, COLOR_SEP_JPEG8 buffers; its camera clock starts at 127.5 s of a 128 s
 * cycle and ticks 0.1 s a frame, so it wraps. Globals let the test steer faults and see the lifecycle.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ladybug.h"

int fake_cameras = 1;
int fake_cols = 16;
int fake_rows = 12;
int fake_bad_frame = -1;     /* grab returns LADYBUG_JPEG_ERROR for this frame number */
int fake_timeout_from = -1;  /* from this frame number on, grab times out */
int fake_init_error = 0;     /* returned by ladybugInitializeFromIndex when non-zero */
int fake_started = 0, fake_stopped = 0, fake_destroyed = 0, fake_contexts = 0;
char fake_config_path[256] = "";

struct fake_context {
    int initialized, running, frame;
    LadybugDataFormat format;
    unsigned char *buffer;
    size_t buffer_size;
};

static unsigned char *block = NULL;
static size_t block_size = 0;

int fake_load_block(const char *path)
{
    FILE *f = fopen(path, "rb");
    if (!f) return -1;
    fseek(f, 0, SEEK_END);
    block_size = (size_t)ftell(f);
    fseek(f, 0, SEEK_SET);
    free(block);
    block = malloc(block_size);
    size_t got = fread(block, 1, block_size, f);
    fclose(f);
    return got == block_size ? 0 : -1;
}

LadybugError ladybugCreateContext(LadybugContext *context)
{
    struct fake_context *c = calloc(1, sizeof *c);
    if (!c) return LADYBUG_FAILED;
    *context = c;
    fake_contexts++;
    return LADYBUG_OK;
}

LadybugError ladybugBusEnumerateCameras(LadybugContext context, LadybugCameraInfo *info, unsigned int *size)
{
    (void)context;
    for (unsigned int i = 0; i < *size && i < (unsigned int)fake_cameras; i++) {
        strcpy(info[i].model, "fake5");
        info[i].serialHead = 17092345u + i;
    }
    *size = (unsigned int)fake_cameras;
    return LADYBUG_OK;
}

LadybugError ladybugInitializeFromIndex(LadybugContext context, unsigned int index)
{
    if (fake_init_error) return (LadybugError)fake_init_error;
    if (index >= (unsigned int)fake_cameras) return LADYBUG_FAILED;
    ((struct fake_context *)context)->initialized = 1;
    return LADYBUG_OK;
}

LadybugError ladybugLoadConfig(LadybugContext context, const char *path)
{
    (void)context;
    snprintf(fake_config_path, sizeof fake_config_path, "%s", path ? path : "(from head)");
    return LADYBUG_OK;
}

LadybugError ladybugStart(LadybugContext context, LadybugDataFormat format)
{
    struct fake_context *c = context;
    if (!c->initialized) return LADYBUG_FAILED;
    if (format == LADYBUG_DATAFORMAT_COLOR_SEP_JPEG8 && !block) return LADYBUG_FAILED;
    c->format = format;
    c->running = 1;
    c->frame = 0;
    c->buffer_size = format == LADYBUG_DATAFORMAT_RAW8 ? (size_t)6 * fake_cols * fake_rows : block_size;
    c->buffer = malloc(c->buffer_size);
    fake_started++;
    return LADYBUG_OK;
}

LadybugError ladybugGrabImage(LadybugContext context, LadybugImage *image)
{
    struct fake_context *c = context;
    if (!c->running) return LADYBUG_NOT_STARTED;
    int k = c->frame++;
    if (fake_timeout_from >= 0 && k >= fake_timeout_from) return LADYBUG_TIMEOUT;
    if (k == fake_bad_frame) return LADYBUG_JPEG_ERROR;
    if (c->format == LADYBUG_DATAFORMAT_RAW8) {
        size_t per_camera = (size_t)fake_cols * fake_rows;
        for (int cam = 0; cam < 6; cam++) memset(c->buffer + cam * per_camera, 40 * cam + k, per_camera);
    } else {
        memcpy(c->buffer, block, block_size);
    }
    memset(image, 0, sizeof *image);
    image->uiCols = (unsigned int)fake_cols;
    image->uiRows = (unsigned int)fake_rows;
    long ticks = 1020000L + k * 800L; /* 125 us cycles: 127.5 s + 0.1 s per frame, 128 s cycle */
    long in_cycle = ticks % (128 * 8000);
    image->timeStamp.ulCycleSeconds = (unsigned long long)(in_cycle / 8000);
    image->timeStamp.ulCycleCount = (unsigned short)(in_cycle % 8000);
    image->imageInfo.ulTimeSeconds = 1700000000ull + (unsigned long long)k;
    image->imageInfo.ulTimeMicroSeconds = 250000u;
    image->imageInfo.ulSequenceId = 1000u + (unsigned int)k;
    image->dataFormat = c->format;
    image->pData = c->buffer;
    image->uiDataSizeBytes = (unsigned int)c->buffer_size;
    return LADYBUG_OK;
}

LadybugError ladybugGetAbsProperty(LadybugContext context, LadybugProperty property, float *value)
{
    (void)context;
    if (property == LADYBUG_SHUTTER) *value = 2.5f; /* ms */
    else if (property == LADYBUG_GAIN) *value = 6.0f; /* dB */
    else return LADYBUG_FAILED;
    return LADYBUG_OK;
}

LadybugError ladybugStop(LadybugContext context)
{
    struct fake_context *c = context;
    if (!c->running) return LADYBUG_NOT_STARTED;
    c->running = 0;
    free(c->buffer);
    c->buffer = NULL;
    fake_stopped++;
    return LADYBUG_OK;
}

LadybugError ladybugDestroyContext(LadybugContext *context)
{
    free(*context);
    *context = NULL;
    fake_destroyed++;
    return LADYBUG_OK;
}

const char *ladybugErrorToString(LadybugError error)
{
    static char text[64];
    snprintf(text, sizeof text, "fake Ladybug error %d", (int)error);
    return text;
}
