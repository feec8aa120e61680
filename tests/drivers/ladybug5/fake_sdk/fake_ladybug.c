/*
 * A fake libladybug for rigd's tests, built from fake_sdk/ladybug.h (the real struct layouts).
 *
 * Frames: RAW8 / RAW16 full sensor images with a border of bright masked pixels (fake_border_*), the useful
 * image a flat colour per camera (B = 20 + 30 cam, G = 100 + frame, R = 220 - 20 cam) mosaiced with the Bayer
 * pattern fake_stippled (for the full image's top-left pixel); RAW16 is the same << 8. COLOR_SEP_JPEG8 serves a
 * loaded frame block. The camera clock starts at 127.5 s of the 128 s cycle and ticks 0.1 s a frame.
 * Geometry: per camera an OpenCV-like lens (focal fake_focal, centre, k1, k2) and Euler ZYX extrinsics; a
 * configuration file "FAKECAL <k1> <k2> <focal>" replaces the lens. The rectified pinhole's focal length is the raw
 * lens's times fake_rect_focal_scale (a real Ladybug5's SDK reports 443-457 px at 2448x2048, where the raw lens is
 * about 1275 px), scaled to the rectified resolution, which is the rectified
 * off-screen size; with fake_size_needs_configure that size is ignored unless the rectified images were configured
 * first (then the geometry asks for a resolution). Globals steer faults and record calls.
 * Renderer: ladybugConvertImage fills each camera's texture with its flat colour (from the image's sequence id),
 * ladybugRenderOffScreenImage places the six textures side by side (camera c in the c-th sixth of the columns,
 * nearest-neighbour resampled) in a BGR image of the panoramic off-screen size; fake_render_log records the
 * configuration, geometry and renderer calls in order (M method, C configure, S off-screen size, F focal length,
 * V convert, U update textures, R render, G 3D map).
 * 3D map: each sampled raw pixel's ray (the same lens, from the camera centre) meets the sphere of the set radius
 * around the head centre, rotated by the set mesh rotation; fake_headless refuses every renderer call (configure,
 * off-screen size) as an SDK without an OpenGL context might, fake_map_error makes ladybugGet3dMap fail.
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ladybug.h"
#include "ladybuggeom.h"
#include "ladybugrenderer.h"

int fake_cameras = 1;
int fake_cols = 16, fake_rows = 12;
int fake_border_top = 1, fake_border_bottom = 2, fake_border_left = 3, fake_border_right = 1;
int fake_stippled = LADYBUG_RGGB;   /* in every LadybugImage */
int fake_tile = LADYBUG_RGGB;       /* from ladybugGetColorTileFormat */
int fake_bad_frame = -1;            /* grab returns LADYBUG_JPEG_ERROR for this frame number */
int fake_timeout_from = -1;         /* from this frame number on, grab times out */
int fake_init_error = 0;            /* returned by the initialise calls when non-zero */
int fake_exposure_error = 0;        /* ladybugGetAbsProperty fails when non-zero */
int fake_started = 0, fake_stopped = 0, fake_destroyed = 0, fake_contexts = 0;
int fake_initialized_serial = -1, fake_initialized_index = -1;
int fake_enumerated_before_init = 0; /* ladybugBusEnumerateCameras was called on a context not yet initialised */
int fake_grab_timeout = -1, fake_timeout_set_after_start = 0;
int fake_rect_cols = 0, fake_rect_rows = 0;
int fake_size_needs_configure = 0; /* the rectified size is taken only for configured rectified images */
char fake_config_path[256] = "";
double fake_focal = 10.0, fake_k1 = -0.05, fake_k2 = 0.01;
double fake_rect_focal_scale = 1.0; /* rectified / raw focal length */
int fake_pano_cols = 2048, fake_pano_rows = 1024; /* the SDK's default panoramic size */
int fake_color_method = -1, fake_configured = 0, fake_texture_format = -1;
int fake_configure_error = 0;        /* returned by ladybugConfigureOutputImages when non-zero */
int fake_render_error_at = -1;       /* this render call (0-based) returns LADYBUG_GPU_ERROR */
int fake_renders = 0;
int fake_headless = 0;               /* configure and off-screen size return LADYBUG_INVALID_OPENGL_RENDERING_CONTEXT */
int fake_map_error = 0;              /* returned by ladybugGet3dMap when non-zero */
double fake_sphere = 20.0, fake_map_rx = 0.0, fake_map_ry = 0.0, fake_map_rz = 0.0; /* the SDK's defaults */
char fake_render_log[256] = "";

struct fake_context {
    int initialized, running, frame;
    LadybugDataFormat format;
    unsigned char *buffer;
    size_t buffer_size;
    int tex_cols, tex_rows, textures_ready;
    unsigned char *textures[6]; /* BGR, 8 bit, tex_cols x tex_rows */
    unsigned char *rendered;
};

static void log_call(char c)
{
    size_t n = strlen(fake_render_log);
    if (n + 1 < sizeof fake_render_log) {
        fake_render_log[n] = c;
        fake_render_log[n + 1] = '\0';
    }
}

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
    if (!c) return LADYBUG_MEMORY_ALLOC_ERROR;
    *context = c;
    fake_contexts++;
    return LADYBUG_OK;
}

LadybugError ladybugBusEnumerateCameras(LadybugContext context, LadybugCameraInfo *info, unsigned int *size)
{
    if (!context) return LADYBUG_INVALID_CONTEXT;
    if (!((struct fake_context *)context)->initialized) fake_enumerated_before_init = 1;
    for (unsigned int i = 0; i < *size && i < (unsigned int)fake_cameras; i++) {
        memset(&info[i], 0, sizeof info[i]);
        info[i].serialBase = info[i].serialHead = 17092345u + i;
        info[i].bIsColourCamera = true;
        info[i].deviceType = LADYBUG_DEVICE_LADYBUG5P;
        snprintf(info[i].pszModelName, sizeof info[i].pszModelName, "Ladybug5+ (fake %u)", i);
        info[i].interfaceType = LADYBUG_INTERFACE_USB3;
    }
    *size = (unsigned int)fake_cameras;
    return LADYBUG_OK;
}

static LadybugError initialize(LadybugContext context, int index)
{
    if (fake_init_error) return (LadybugError)fake_init_error;
    if (index < 0 || index >= fake_cameras) return LADYBUG_FAILED;
    ((struct fake_context *)context)->initialized = 1;
    return LADYBUG_OK;
}

LadybugError ladybugInitializeFromIndex(LadybugContext context, unsigned int index)
{
    fake_initialized_index = (int)index;
    return initialize(context, (int)index);
}

LadybugError ladybugInitializeFromSerialNumber(LadybugContext context, LadybugSerialNumber serial)
{
    fake_initialized_serial = (int)serial;
    return initialize(context, (int)(serial - 17092345u));
}

LadybugError ladybugLoadConfig(LadybugContext context, const char *path)
{
    (void)context;
    snprintf(fake_config_path, sizeof fake_config_path, "%s", path ? path : "(from head)");
    if (!path) return LADYBUG_OK;
    FILE *f = fopen(path, "r");
    if (!f) return LADYBUG_COULD_NOT_OPEN_FILE;
    int got = fscanf(f, "FAKECAL %lf %lf %lf", &fake_k1, &fake_k2, &fake_focal);
    fclose(f);
    return got == 3 ? LADYBUG_OK : LADYBUG_INVALID_CONFIG_FILE;
}

LadybugError ladybugGetColorTileFormat(LadybugContext context, LadybugStippledFormat *format)
{
    (void)context;
    *format = (LadybugStippledFormat)fake_tile;
    return LADYBUG_OK;
}

LadybugError ladybugSetGrabTimeout(LadybugContext context, unsigned int timeout)
{
    if (((struct fake_context *)context)->running) fake_timeout_set_after_start = 1;
    fake_grab_timeout = (int)timeout;
    return LADYBUG_OK;
}

static size_t pixel_bytes(LadybugDataFormat format)
{
    return format == LADYBUG_DATAFORMAT_RAW16 ? 2 : 1;
}

LadybugError ladybugStart(LadybugContext context, LadybugDataFormat format)
{
    struct fake_context *c = context;
    if (!c->initialized) return LADYBUG_NOT_INITIALIZED;
    if (format == LADYBUG_DATAFORMAT_COLOR_SEP_JPEG8 && !block) return LADYBUG_FAILED;
    size_t full = (size_t)(fake_cols + fake_border_left + fake_border_right) *
                  (size_t)(fake_rows + fake_border_top + fake_border_bottom);
    c->format = format;
    c->running = 1;
    c->frame = 0;
    c->buffer_size = format == LADYBUG_DATAFORMAT_COLOR_SEP_JPEG8 ? block_size : 6 * full * pixel_bytes(format);
    c->buffer = malloc(c->buffer_size);
    fake_started++;
    return LADYBUG_OK;
}

/* The colour (0 B, 1 G, 2 R) at full-image pixel (row, col): the image's pattern, the tile format's for DEFAULT. */
static int channel_at(int row, int col)
{
    static const char *patterns[] = {"BGGR", "GBRG", "GRBG", "RGGB"};
    int pattern = fake_stippled == LADYBUG_DEFAULT ? fake_tile : fake_stippled;
    char colour = patterns[pattern - LADYBUG_BGGR][2 * (row % 2) + col % 2];
    return colour == 'B' ? 0 : colour == 'G' ? 1 : 2;
}

static void fill_raw(struct fake_context *c, int frame)
{
    int full_cols = fake_cols + fake_border_left + fake_border_right;
    int full_rows = fake_rows + fake_border_top + fake_border_bottom;
    size_t bytes = pixel_bytes(c->format);
    for (int cam = 0; cam < 6; cam++) {
        int bgr[3] = {20 + 30 * cam, 100 + frame, 220 - 20 * cam};
        for (int r = 0; r < full_rows; r++) {
            for (int col = 0; col < full_cols; col++) {
                int inside = r >= fake_border_top && r < fake_border_top + fake_rows && col >= fake_border_left &&
                             col < fake_border_left + fake_cols;
                unsigned int value = inside ? (unsigned int)bgr[channel_at(r, col)] : 255u; /* masked: bright */
                size_t at = ((size_t)cam * full_rows * full_cols + (size_t)r * full_cols + col) * bytes;
                if (bytes == 1) {
                    c->buffer[at] = (unsigned char)value;
                } else { /* little-endian 16-bit words, the value in the top byte */
                    c->buffer[at] = 0;
                    c->buffer[at + 1] = (unsigned char)value;
                }
            }
        }
    }
}

LadybugError ladybugGrabImage(LadybugContext context, LadybugImage *image)
{
    struct fake_context *c = context;
    if (!c->running) return LADYBUG_NOT_STARTED;
    int k = c->frame++;
    if (fake_timeout_from >= 0 && k >= fake_timeout_from) return LADYBUG_TIMEOUT;
    if (k == fake_bad_frame) return LADYBUG_JPEG_ERROR;
    if (c->format == LADYBUG_DATAFORMAT_COLOR_SEP_JPEG8) memcpy(c->buffer, block, block_size);
    else fill_raw(c, k);
    memset(image, 0, sizeof *image);
    image->uiCols = (unsigned int)fake_cols;
    image->uiRows = (unsigned int)fake_rows;
    image->imageBorder.uiTopRows = (unsigned int)fake_border_top;
    image->imageBorder.uiBottomRows = (unsigned int)fake_border_bottom;
    image->imageBorder.uiLeftCols = (unsigned int)fake_border_left;
    image->imageBorder.uiRightCols = (unsigned int)fake_border_right;
    image->uiFullCols = (unsigned int)(fake_cols + fake_border_left + fake_border_right);
    image->uiFullRows = (unsigned int)(fake_rows + fake_border_top + fake_border_bottom);
    image->resolution = LADYBUG_RESOLUTION_2464x2048;
    long ticks = 1020000L + k * 800L; /* 125 us cycles: 127.5 s + 0.1 s per frame, 128 s cycle */
    long in_cycle = ticks % (128 * 8000);
    image->timeStamp.ulCycleSeconds = (unsigned int)(in_cycle / 8000);
    image->timeStamp.ulCycleCount = (unsigned int)(in_cycle % 8000);
    image->imageInfo.ulFingerprint = 0xCAFEBABE;
    image->imageInfo.ulTimeSeconds = 1700000000u + (unsigned int)k;
    image->imageInfo.ulTimeMicroSeconds = 250000u;
    image->imageInfo.ulSequenceId = 1000u + (unsigned int)k;
    image->dataFormat = c->format;
    image->pData = c->buffer;
    image->bStippled = true;
    image->stippledFormat = (LadybugStippledFormat)fake_stippled;
    image->uiDataSizeBytes = (unsigned int)c->buffer_size;
    return LADYBUG_OK;
}

LadybugError ladybugGetAbsProperty(LadybugContext context, LadybugProperty property, float *value)
{
    (void)context;
    if (fake_exposure_error) return LADYBUG_FAILED;
    if (property == LADYBUG_SHUTTER) *value = 2.5f; /* ms */
    else if (property == LADYBUG_GAIN) *value = 6.0f; /* dB */
    else return LADYBUG_NOT_SUPPORTED;
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
    struct fake_context *c = *context;
    for (int cam = 0; cam < 6; cam++) free(c->textures[cam]);
    free(c->rendered);
    free(*context);
    *context = NULL;
    fake_destroyed++;
    return LADYBUG_OK;
}

const char *ladybugErrorToString(const LadybugError error)
{
    static char text[64];
    snprintf(text, sizeof text, "fake Ladybug error %d", (int)error);
    return text;
}

/* -- geometry ------------------------------------------------------------------------------------------------ */

LadybugError ladybugSetOffScreenImageSize(LadybugContext context, LadybugOutputImage type, unsigned int width,
                                          unsigned int height)
{
    (void)context;
    log_call('S');
    if (fake_headless) return LADYBUG_INVALID_OPENGL_RENDERING_CONTEXT;
    int rectified = (fake_configured & LADYBUG_ALL_RECTIFIED_IMAGES) == LADYBUG_ALL_RECTIFIED_IMAGES;
    if ((type & LADYBUG_ALL_RECTIFIED_IMAGES) && (rectified || !fake_size_needs_configure)) {
        fake_rect_cols = (int)width;
        fake_rect_rows = (int)height;
    }
    if (type & LADYBUG_PANORAMIC) {
        fake_pano_cols = (int)width;
        fake_pano_rows = (int)height;
    }
    return LADYBUG_OK;
}

static double centre_x(unsigned int cam) { return (fake_cols - 1) / 2.0 + 0.3 * cam; }
static double centre_y(unsigned int cam) { return (fake_rows - 1) / 2.0 - 0.2 * cam; }
static double scale(void) { return (double)fake_rect_cols / fake_cols; }
static double rect_focal(void) { return fake_focal * fake_rect_focal_scale * scale(); }
static double rect_cx(unsigned int cam) { return (centre_x(cam) + 0.5) * scale() - 0.5; }
static double rect_cy(unsigned int cam) { return (centre_y(cam) + 0.5) * scale() - 0.5; }

static LadybugError geometry_ready(unsigned int cam)
{
    if (!fake_rect_cols) return LADYBUG_NEED_RECTIFY_RESOLUTION;
    return cam < 6 ? LADYBUG_OK : LADYBUG_INVALID_ARGUMENT;
}

LadybugError ladybugGetCameraUnitFocalLength(LadybugContext context, unsigned int cam, double *focal)
{
    (void)context;
    log_call('F');
    LadybugError error = geometry_ready(cam);
    if (error == LADYBUG_OK) *focal = rect_focal();
    return error;
}

LadybugError ladybugGetCameraUnitImageCenter(LadybugContext context, unsigned int cam, double *cx, double *cy)
{
    (void)context;
    LadybugError error = geometry_ready(cam);
    if (error != LADYBUG_OK) return error;
    *cx = rect_cx(cam);
    *cy = rect_cy(cam);
    return LADYBUG_OK;
}

LadybugError ladybugGetCameraUnitExtrinsics(LadybugContext context, unsigned int cam, double e[6])
{
    (void)context;
    if (cam >= 6) return LADYBUG_INVALID_ARGUMENT;
    double yaw = cam < 5 ? cam * 72.0 * M_PI / 180.0 : 0.0;
    e[0] = 0.01 * cam;                       /* rx */
    e[1] = cam < 5 ? M_PI / 2 : 0.0;         /* ry: side sensors look sideways, the top one up */
    e[2] = yaw;                              /* rz */
    e[3] = 0.045 * cos(yaw) * (cam < 5);     /* m */
    e[4] = 0.045 * sin(yaw) * (cam < 5);
    e[5] = cam < 5 ? 0.0 : 0.045;
    return LADYBUG_OK;
}

static double radial(double x, double y)
{
    double r2 = x * x + y * y;
    return 1.0 + r2 * (fake_k1 + r2 * fake_k2);
}

LadybugError ladybugRectifyPixel(LadybugContext context, unsigned int cam, double row, double col, double *rrow,
                                 double *rcol)
{
    (void)context;
    LadybugError error = geometry_ready(cam);
    if (error != LADYBUG_OK) return error;
    double xd = (col - centre_x(cam)) / fake_focal, yd = (row - centre_y(cam)) / fake_focal, x = xd, y = yd;
    for (int i = 0; i < 100; i++) {
        double r = radial(x, y);
        x = xd / r;
        y = yd / r;
    }
    *rcol = rect_focal() * x + rect_cx(cam);
    *rrow = rect_focal() * y + rect_cy(cam);
    return LADYBUG_OK;
}

LadybugError ladybugUnrectifyPixel(LadybugContext context, unsigned int cam, double rrow, double rcol, double *row,
                                   double *col)
{
    (void)context;
    LadybugError error = geometry_ready(cam);
    if (error != LADYBUG_OK) return error;
    double x = (rcol - rect_cx(cam)) / rect_focal(), y = (rrow - rect_cy(cam)) / rect_focal(), r = radial(x, y);
    *col = fake_focal * x * r + centre_x(cam);
    *row = fake_focal * y * r + centre_y(cam);
    if (*col < 0 || *col > fake_cols - 1 || *row < 0 || *row > fake_rows - 1) *row = *col = -1.0; /* outside */
    return LADYBUG_OK;
}

static void craig(const double e[3], double r[9])
{
    double cx = cos(e[0]), sx = sin(e[0]), cy = cos(e[1]), sy = sin(e[1]), cz = cos(e[2]), sz = sin(e[2]);
    double m[9] = {cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx,
                   sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx,
                   -sy,     cy * sx,                cy * cx};
    memcpy(r, m, sizeof m);
}

LadybugError ladybugSet3dMapSphereSize(LadybugContext context, double radius)
{
    (void)context;
    fake_sphere = radius;
    return LADYBUG_OK;
}

LadybugError ladybugGet3dMapSphereSize(LadybugContext context, double *radius)
{
    (void)context;
    *radius = fake_sphere;
    return LADYBUG_OK;
}

LadybugError ladybugSet3dMapRotation(LadybugContext context, double rx, double ry, double rz)
{
    (void)context;
    fake_map_rx = rx, fake_map_ry = ry, fake_map_rz = rz;
    return LADYBUG_OK;
}

LadybugError ladybugGet3dMapRotation(LadybugContext context, double *rx, double *ry, double *rz)
{
    (void)context;
    *rx = fake_map_rx, *ry = fake_map_ry, *rz = fake_map_rz;
    return LADYBUG_OK;
}

static LadybugImage3d map3d[6];

/* the point on the sphere of the ray of raw pixel (col, row) of camera cam, mesh-rotated */
static void sphere_point(unsigned int cam, double col, double row, LadybugPoint3d *out)
{
    double xd = (col - centre_x(cam)) / fake_focal, yd = (row - centre_y(cam)) / fake_focal, x = xd, y = yd;
    for (int i = 0; i < 100; i++) {
        double r = radial(x, y);
        x = xd / r;
        y = yd / r;
    }
    double e[6], r[9], mesh[9], rot[3] = {fake_map_rx, fake_map_ry, fake_map_rz}, d[3], p[3];
    ladybugGetCameraUnitExtrinsics(NULL, cam, e);
    craig(e, r);
    craig(rot, mesh);
    double n = sqrt(x * x + y * y + 1.0);
    for (int k = 0; k < 3; k++) d[k] = (r[3 * k] * x + r[3 * k + 1] * y + r[3 * k + 2]) / n;
    double td = e[3] * d[0] + e[4] * d[1] + e[5] * d[2], tt = e[3] * e[3] + e[4] * e[4] + e[5] * e[5];
    double s = -td + sqrt(td * td - (tt - fake_sphere * fake_sphere));
    for (int k = 0; k < 3; k++) p[k] = e[3 + k] + s * d[k];
    out->fX = (float)(mesh[0] * p[0] + mesh[1] * p[1] + mesh[2] * p[2]);
    out->fY = (float)(mesh[3] * p[0] + mesh[4] * p[1] + mesh[5] * p[2]);
    out->fZ = (float)(mesh[6] * p[0] + mesh[7] * p[1] + mesh[8] * p[2]);
}

LadybugError ladybugGet3dMap(LadybugContext context, unsigned int cam, unsigned int grid_cols, unsigned int grid_rows,
                             unsigned int src_cols, unsigned int src_rows, bool centre, const LadybugImage3d **image)
{
    (void)context;
    log_call('G');
    if (fake_map_error) return (LadybugError)fake_map_error;
    if (cam >= 6 || !grid_cols || !grid_rows || grid_cols != src_cols || grid_rows != src_rows || !centre)
        return LADYBUG_INVALID_ARGUMENT; /* the fake samples pixel centres of the source image only */
    LadybugImage3d *m = &map3d[cam];
    free(m->ppoints);
    m->uiCols = grid_cols, m->uiRows = grid_rows;
    m->ppoints = calloc((size_t)grid_cols * grid_rows, sizeof(LadybugPoint3d));
    for (unsigned int i = 0; i < grid_rows; i++)
        for (unsigned int j = 0; j < grid_cols; j++)
            sphere_point(cam, (j + 0.5) * fake_cols / src_cols - 0.5, (i + 0.5) * fake_rows / src_rows - 0.5,
                         &m->ppoints[i * grid_cols + j]);
    *image = m;
    return LADYBUG_OK;
}

/* -- renderer ------------------------------------------------------------------------------------------------ */

LadybugError ladybugSetColorProcessingMethod(LadybugContext context, LadybugColorProcessingMethod method)
{
    (void)context;
    log_call('M');
    fake_color_method = (int)method;
    return LADYBUG_OK;
}

LadybugError ladybugConfigureOutputImages(LadybugContext context, unsigned int types)
{
    (void)context;
    log_call('C');
    if (fake_headless) return LADYBUG_INVALID_OPENGL_RENDERING_CONTEXT;
    if (fake_configure_error) return (LadybugError)fake_configure_error;
    fake_configured = (int)types;
    return LADYBUG_OK;
}

static int texture_bytes(LadybugPixelFormat format)
{
    return format == LADYBUG_BGRU ? 4 : format == LADYBUG_BGRU16 ? 8 : 0;
}

/* Each camera's useful image as its flat colour (fill_raw's), BGRU or BGRU16 (the value in the top byte). */
LadybugError ladybugConvertImage(LadybugContext context, const LadybugImage *image, unsigned char **buffers,
                                 LadybugPixelFormat format)
{
    struct fake_context *c = context;
    log_call('V');
    int bytes = texture_bytes(format);
    if (!image || !image->pData || !buffers || !bytes) return LADYBUG_INVALID_ARGUMENT;
    int frame = (int)image->imageInfo.ulSequenceId - 1000;
    size_t pixels = (size_t)image->uiCols * image->uiRows;
    for (int cam = 0; cam < 6; cam++) {
        int bgr[4] = {20 + 30 * cam, 100 + frame, 220 - 20 * cam, 255};
        for (size_t i = 0; i < pixels; i++) {
            for (int ch = 0; ch < 4; ch++) {
                if (bytes == 4) {
                    buffers[cam][4 * i + ch] = (unsigned char)bgr[ch];
                } else {
                    buffers[cam][8 * i + 2 * ch] = 0;
                    buffers[cam][8 * i + 2 * ch + 1] = (unsigned char)bgr[ch];
                }
            }
        }
    }
    c->tex_cols = (int)image->uiCols;
    c->tex_rows = (int)image->uiRows;
    return LADYBUG_OK;
}

LadybugError ladybugUpdateTextures(LadybugContext context, unsigned int cameras, const unsigned char **buffers,
                                   LadybugPixelFormat format)
{
    struct fake_context *c = context;
    log_call('U');
    int bytes = texture_bytes(format);
    if (cameras != LADYBUG_NUM_CAMERAS || !buffers || !bytes || !c->tex_cols) return LADYBUG_INVALID_ARGUMENT;
    fake_texture_format = (int)format;
    size_t pixels = (size_t)c->tex_cols * c->tex_rows;
    for (int cam = 0; cam < 6; cam++) {
        free(c->textures[cam]);
        c->textures[cam] = malloc(3 * pixels);
        for (size_t i = 0; i < pixels; i++)
            for (int ch = 0; ch < 3; ch++) /* the top byte of a 16-bit little-endian word */
                c->textures[cam][3 * i + ch] = buffers[cam][bytes * i + (bytes / 4) * ch + (bytes / 4 - 1)];
    }
    c->textures_ready = 1;
    return LADYBUG_OK;
}

LadybugError ladybugRenderOffScreenImage(LadybugContext context, LadybugOutputImage type, LadybugPixelFormat format,
                                         LadybugProcessedImage *out)
{
    struct fake_context *c = context;
    log_call('R');
    int k = fake_renders++;
    if (!(fake_configured & (int)type)) return LADYBUG_OFFSCREEN_BUFFER_INIT_ERROR;
    if (!c->textures_ready) return LADYBUG_OPENGL_TEXTUREIMAGE_NOT_UPDATED;
    if (format != LADYBUG_BGR || type != LADYBUG_PANORAMIC) return LADYBUG_NOT_SUPPORTED;
    if (k == fake_render_error_at) return LADYBUG_GPU_ERROR;
    int cols = fake_pano_cols, rows = fake_pano_rows;
    free(c->rendered);
    c->rendered = malloc((size_t)3 * cols * rows);
    for (int r = 0; r < rows; r++) {
        for (int col = 0; col < cols; col++) {
            int cam = col * 6 / cols, start = (cam * cols + 5) / 6, end = ((cam + 1) * cols + 5) / 6;
            int sc = (col - start) * c->tex_cols / (end - start), sr = r * c->tex_rows / rows;
            memcpy(&c->rendered[3 * ((size_t)r * cols + col)], &c->textures[cam][3 * ((size_t)sr * c->tex_cols + sc)], 3);
        }
    }
    if (out) {
        memset(out, 0, sizeof *out);
        out->uiCols = (unsigned int)cols;
        out->uiRows = (unsigned int)rows;
        out->pData = c->rendered;
        out->pixelFormat = format;
    }
    return LADYBUG_OK;
}
