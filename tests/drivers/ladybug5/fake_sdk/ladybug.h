/*
 * rigd's stand-in for the Ladybug SDK header, for tests only. Our own minimal declarations: the function
 * names and member names of the real API, but our own (deliberately different) struct layout and enum
 * values, so the tests prove the binding takes every number from layout_probe.c, none hard-coded.
 */
#ifndef RIGD_FAKE_LADYBUG_H
#define RIGD_FAKE_LADYBUG_H

typedef void *LadybugContext;

typedef enum LadybugError {
    LADYBUG_OK = 0,
    LADYBUG_FAILED = 101,
    LADYBUG_NOT_STARTED = 102,
    LADYBUG_TIMEOUT = 103,
    LADYBUG_IMAGE_TOO_SMALL = 104,
    LADYBUG_JPEG_ERROR = 105,
    LADYBUG_JPEG_HEADER_ERROR = 106,
    LADYBUG_JPEG_INCOMPLETE_COMPRESSION = 107,
    LADYBUG_JPEG_NO_IMAGE = 108,
    LADYBUG_CORRUPTED_IMAGE_DATA = 109,
    LADYBUG_BAD_VOLTAGE = 110,
    LADYBUG_BAD_INTERFACE = 111
} LadybugError;

typedef enum LadybugDataFormat { LADYBUG_DATAFORMAT_RAW8 = 21, LADYBUG_DATAFORMAT_COLOR_SEP_JPEG8 = 24 } LadybugDataFormat;
typedef enum LadybugProperty { LADYBUG_SHUTTER = 31, LADYBUG_GAIN = 32 } LadybugProperty;

typedef struct LadybugTimestamp {
    unsigned short ulCycleCount;
    unsigned long long ulCycleSeconds;
} LadybugTimestamp;

typedef struct LadybugImageInfo {
    unsigned int ulSequenceId;
    unsigned int ulTimeMicroSeconds;
    unsigned long long ulTimeSeconds;
} LadybugImageInfo;

typedef struct LadybugImage {
    char reserved[5];
    LadybugImageInfo imageInfo;
    unsigned int uiRows;
    unsigned int uiCols;
    unsigned char *pData;
    LadybugTimestamp timeStamp;
    unsigned int uiDataSizeBytes;
    LadybugDataFormat dataFormat;
} LadybugImage;

typedef struct LadybugCameraInfo {
    char model[7];
    unsigned int serialHead;
} LadybugCameraInfo;

LadybugError ladybugCreateContext(LadybugContext *context);
LadybugError ladybugBusEnumerateCameras(LadybugContext context, LadybugCameraInfo *info, unsigned int *size);
LadybugError ladybugInitializeFromIndex(LadybugContext context, unsigned int index);
LadybugError ladybugLoadConfig(LadybugContext context, const char *path);
LadybugError ladybugStart(LadybugContext context, LadybugDataFormat format);
LadybugError ladybugGrabImage(LadybugContext context, LadybugImage *image);
LadybugError ladybugGetAbsProperty(LadybugContext context, LadybugProperty property, float *value);
LadybugError ladybugStop(LadybugContext context);
LadybugError ladybugDestroyContext(LadybugContext *context);
const char *ladybugErrorToString(LadybugError error);

#endif
