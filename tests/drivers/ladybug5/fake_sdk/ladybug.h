/*
 * rigd's stand-in for FLIR's ladybug.h, for tests only; written for rigd, not copied.
 *
 * The structs declare the same members, of the same types, in the same order as the Ladybug SDK's ladybug.h
 * of 2017 (the version public projects vendor), so on the same compiler they have the real offsets: the
 * border, full size and stippled format of LadybugImage sit where the binding will find them on a rig. The
 * enums have the real members in the real order; RIGD_FAKE_SHIFT (default 0: the real values) moves all
 * of them, so a second build proves the binding takes every number from layout_probe.c.
 *
 * Valid C and C++ (FLIR's header is C++ only: constructors and default arguments, left out here).
 */
#ifndef RIGD_FAKE_LADYBUG_H
#define RIGD_FAKE_LADYBUG_H

#include <string.h>
#ifndef __cplusplus
#include <stdbool.h>
#endif

#ifndef RIGD_FAKE_SHIFT
#define RIGD_FAKE_SHIFT 0
#endif

#ifdef __cplusplus
extern "C" {
#endif

typedef void *LadybugContext;
typedef unsigned int LadybugSerialNumber;

#define LADYBUG_NUM_CAMERAS 6
#define LADYBUG_NUM_JPEGS 24
#define LADYBUG_INFINITE 0xFFFFFFFF

typedef enum LadybugError {
    LADYBUG_OK,
    LADYBUG_FAILED = 1 + RIGD_FAKE_SHIFT,
    LADYBUG_INVALID_ARGUMENT,
    LADYBUG_INVALID_CONTEXT,
    LADYBUG_NOT_IMPLEMENTED,
    LADYBUG_NOT_SUPPORTED,
    LADYBUG_ALREADY_INITIALIZED,
    LADYBUG_ALREADY_STARTED,
    LADYBUG_COULD_NOT_OPEN_FILE,
    LADYBUG_MEMORY_ALLOC_ERROR,
    LADYBUG_ERROR_DISK_NOT_ENOUGH_SPACE,
    LADYBUG_STREAM_FILE_NOT_OPENED,
    LADYBUG_INVALID_STREAM_FILE_NAME,
    LADYBUG_NOT_INITIALIZED,
    LADYBUG_NOT_STARTED,
    LADYBUG_MAX_BANDWIDTH_EXCEEDED,
    LADYBUG_INVALID_VIDEO_SETTING,
    LADYBUG_NEED_RECTIFY_RESOLUTION,
    LADYBUG_DEPRECATED,
    LADYBUG_IMAGE_TOO_SMALL,
    LADYBUG_TIMEOUT,
    LADYBUG_TOO_MANY_LOCKED_BUFFERS,
    LADYBUG_CALIBRATION_FILE_NOT_FOUND,
    LADYBUG_JPEG_ERROR,
    LADYBUG_JPEG_HEADER_ERROR,
    LADYBUG_JPEG_INCOMPLETE_COMPRESSION,
    LADYBUG_JPEG_NO_IMAGE,
    LADYBUG_CORRUPTED_IMAGE_DATA,
    LADYBUG_OFFSCREEN_BUFFER_INIT_ERROR,
    LADYBUG_FRAMEBUFFER_UNSUPPORTED_FORMAT,
    LADYBUG_FRAMEBUFFER_INCOMPLETE,
    LADYBUG_GPS_COULD_NOT_BE_STARTED,
    LADYBUG_GPS_NOT_STARTED,
    LADYBUG_GPS_NO_DATA,
    LADYBUG_GPS_NO_DATA_FOR_THIS_SENTENCE,
    LADYBUG_GPS_COMM_PORT_IN_USE,
    LADYBUG_GPS_COMM_PORT_DOES_NOT_EXIST,
    LADYBUG_OPENGL_DISPLAYLIST_NOT_INITIALIZED,
    LADYBUG_OPENGL_TEXTUREIMAGE_NOT_UPDATED,
    LADYBUG_INVALID_OPENGL_DEVICE_CONTEXT,
    LADYBUG_INVALID_OPENGL_RENDERING_CONTEXT,
    LADYBUG_INVALID_OPENGL_TEXTURE,
    LADYBUG_INVALID_OPENGL_OPERATION,
    LADYBUG_NOT_ENOUGH_RESOURCE_FOR_OPENGL_TEXTURE,
    LADYBUG_SHARING_DISPLAYLIST_FAILED,
    LADYBUG_INVALID_OFFSCREEN_BUFFER_SIZE,
    LADYBUG_STILL_WORKING,
    LADYBUG_CORRUPTED_PGR_STREAM,
    LADYBUG_GPU_CUDA_DRIVER_ERROR,
    LADYBUG_NO_CUDA_DEVICE,
    LADYBUG_GPU_ERROR,
    LADYBUG_LOW_LEVEL_FAILURE,
    LADYBUG_REGISTER_FAILED,
    LADYBUG_ISOCH_FAILED,
    LADYBUG_RETRIEVE_BUFFER_FAILED,
    LADYBUG_IMAGE_LIBRARY_FAILED,
    LADYBUG_BUS_MASTER_FAILED,
    LADYBUG_ERROR_UNKNOWN,
    LADYBUG_BAD_VOLTAGE,
    LADYBUG_BAD_INTERFACE,
    LADYBUG_OVEREXPOSED,
    LADYBUG_INTERNAL_ERROR,
    LADYBUG_NO_OVERLAP,
    LADYBUG_INVALID_CONFIG_FILE,
    LADYBUG_NUM_LADYBUG_ERRORS,
    LADYBUG_ERROR_FORCE_QUADLET = 0x7FFFFFFF
} LadybugError;

typedef enum LadybugBusSpeed {
    LADYBUG_S100, LADYBUG_S200, LADYBUG_S400, LADYBUG_S800, LADYBUG_S1600, LADYBUG_S3200, LADYBUG_S_FASTEST,
    LADYBUG_SPEED_UNKNOWN = -1,
    LADYBUG_SPEED_FORCE_QUADLET = 0x7FFFFFFF
} LadybugBusSpeed;

typedef enum LadybugInterfaceType {
    LADYBUG_INTERFACE_IEEE1394, LADYBUG_INTERFACE_USB2, LADYBUG_INTERFACE_USB3, LADYBUG_INTERFACE_UNKNOWN,
    LADYBUG_INTERFACE_FORCE_QUADLET = 0x7FFFFFFF
} LadybugInterfaceType;

typedef enum LadybugProperty {
    LADYBUG_BRIGHTNESS = RIGD_FAKE_SHIFT, LADYBUG_AUTO_EXPOSURE, LADYBUG_SHARPNESS, LADYBUG_WHITE_BALANCE,
    LADYBUG_HUE, LADYBUG_SATURATION, LADYBUG_GAMMA, LADYBUG_IRIS, LADYBUG_FOCUS, LADYBUG_ZOOM, LADYBUG_PAN,
    LADYBUG_TILT, LADYBUG_SHUTTER, LADYBUG_GAIN, LADYBUG_FRAME_RATE,
    LADYBUG_PROPERTY_FORCE_QUADLET = 0x7FFFFFFF
} LadybugProperty;

typedef enum LadybugDataFormat {
    LADYBUG_DATAFORMAT_RAW8 = 1 + RIGD_FAKE_SHIFT,
    LADYBUG_DATAFORMAT_JPEG8,
    LADYBUG_DATAFORMAT_COLOR_SEP_RAW8,
    LADYBUG_DATAFORMAT_COLOR_SEP_JPEG8,
    LADYBUG_DATAFORMAT_HALF_HEIGHT_RAW8,
    LADYBUG_DATAFORMAT_COLOR_SEP_HALF_HEIGHT_JPEG8,
    LADYBUG_DATAFORMAT_RAW16,
    LADYBUG_DATAFORMAT_COLOR_SEP_JPEG12,
    LADYBUG_DATAFORMAT_HALF_HEIGHT_RAW16,
    LADYBUG_DATAFORMAT_COLOR_SEP_HALF_HEIGHT_JPEG12,
    LADYBUG_DATAFORMAT_RAW12,
    LADYBUG_DATAFORMAT_HALF_HEIGHT_RAW12,
    LADYBUG_NUM_DATAFORMATS,
    LADYBUG_DATAFORMAT_ANY,
    LADYBUG_DATAFORMAT_FORCE_QUADLET = 0x7FFFFFFF
} LadybugDataFormat;

typedef enum LadybugResolution {
    LADYBUG_RESOLUTION_1024x768 = 4,
    LADYBUG_RESOLUTION_1616x1232 = 8,
    LADYBUG_RESOLUTION_2448x2048 = 9,
    LADYBUG_RESOLUTION_2464x2048 = 12,
    LADYBUG_NUM_RESOLUTIONS = 10,
    LADYBUG_RESOLUTION_ANY = 11,
    LADYBUG_RESOLUTION_FORCE_QUADLET = 0x7FFFFFFF
} LadybugResolution;

/* The Bayer pattern: the colours of the top-left 2x2 pixels, row by row. */
typedef enum LadybugStippledFormat {
    LADYBUG_BGGR = RIGD_FAKE_SHIFT, LADYBUG_GBRG, LADYBUG_GRBG, LADYBUG_RGGB, LADYBUG_DEFAULT,
    LADYBUG_STIPPLED_FORCE_QUADLET = 0x7FFFFFFF
} LadybugStippledFormat;

/* The demosaicing methods of ladybugConvertImage (2017 order; older SDKs had NEAREST_NEIGHBOR after EDGE_SENSING). */
typedef enum LadybugColorProcessingMethod {
    LADYBUG_DISABLE = RIGD_FAKE_SHIFT, LADYBUG_EDGE_SENSING, LADYBUG_NEAREST_NEIGHBOR_FAST, LADYBUG_RIGOROUS,
    LADYBUG_DOWNSAMPLE4, LADYBUG_DOWNSAMPLE16, LADYBUG_MONO, LADYBUG_HQLINEAR, LADYBUG_HQLINEAR_GPU,
    LADYBUG_DIRECTIONAL_FILTER, LADYBUG_WEIGHTED_DIRECTIONAL_FILTER,
    LADYBUG_COLOR_FORCE_QUADLET = 0x7FFFFFFF
} LadybugColorProcessingMethod;

/* Pixel formats of converted textures and rendered images (the real bit values, moved by the shift). */
typedef enum LadybugPixelFormat {
    LADYBUG_MONO8 = 0x00000001 + RIGD_FAKE_SHIFT,
    LADYBUG_MONO16 = 0x00000020 + RIGD_FAKE_SHIFT,
    LADYBUG_RAW8 = 0x00000200 + RIGD_FAKE_SHIFT,
    LADYBUG_RAW16 = 0x00000400 + RIGD_FAKE_SHIFT,
    LADYBUG_BGR = 0x10000001 + RIGD_FAKE_SHIFT,
    LADYBUG_BGRU = 0x10000002 + RIGD_FAKE_SHIFT,
    LADYBUG_BGR16 = 0x10000004 + RIGD_FAKE_SHIFT,
    LADYBUG_BGRU16 = 0x10000008 + RIGD_FAKE_SHIFT,
    LADYBUG_BGR16F = 0x10000010 + RIGD_FAKE_SHIFT,
    LADYBUG_BGR32F = 0x10000020 + RIGD_FAKE_SHIFT,
    LADYBUG_RGB = 0x20000001 + RIGD_FAKE_SHIFT,
    LADYBUG_RGBU = 0x20000002 + RIGD_FAKE_SHIFT,
    LADYBUG_RGB16 = 0x20000004 + RIGD_FAKE_SHIFT,
    LADYBUG_RGBU16 = 0x20000008 + RIGD_FAKE_SHIFT,
    LADYBUG_RGB16F = 0x20000010 + RIGD_FAKE_SHIFT,
    LADYBUG_RGB32F = 0x20000020 + RIGD_FAKE_SHIFT,
    LADYBUG_PIXELFORMAT_FORCE_QUADLET = 0x7FFFFFFF,
    LADYBUG_UNSPECIFIED_PIXEL_FORMAT = 0
} LadybugPixelFormat;

typedef enum LadybugDeviceType {
    LADYBUG_DEVICE_LADYBUG, LADYBUG_DEVICE_COMPRESSOR, LADYBUG_DEVICE_LADYBUG3, LADYBUG_DEVICE_LADYBUG5,
    LADYBUG_DEVICE_LADYBUG5P, LADYBUG_DEVICE_UNKNOWN,
    LADYBUG_DEVICE_FORCE_QUADLET = 0x7FFFFFFF
} LadybugDeviceType;

typedef struct LadybugTimestamp {
    long long ulSeconds;
    unsigned int ulMicroSeconds;
    unsigned int ulCycleSeconds;
    unsigned int ulCycleCount;
    unsigned int ulCycleOffset;
} LadybugTimestamp;

typedef struct LadybugImageInfo {
    unsigned int ulFingerprint;
    unsigned int ulVersion;
    unsigned int ulTimeSeconds;
    unsigned int ulTimeMicroSeconds;
    unsigned int ulSequenceId;
    unsigned int ulHRate;
    unsigned int arulGainAdjust[LADYBUG_NUM_CAMERAS];
    unsigned int ulWhiteBalance;
    unsigned int ulBayerGain;
    unsigned int ulBayerMap;
    unsigned int ulBrightness;
    unsigned int ulGamma;
    unsigned int ulSerialNum;
    unsigned int ulShutter[LADYBUG_NUM_CAMERAS];
    unsigned int ulGpsFixQuality;
    bool bPpsStatus;
    bool bGpsStatus;
    double dGPSLatitude;
    double dGPSLongitude;
    double dGPSAltitude;
} LadybugImageInfo;

typedef struct LadybugTriplet {
    float x;
    float y;
    float z;
} LadybugTriplet;

typedef struct LadybugImageHeader {
    unsigned int uiTemperature;
    unsigned int uiHumidity;
    unsigned int uiAirPressure;
    LadybugTriplet compass;
    LadybugTriplet accelerometer;
    LadybugTriplet gyroscope;
    bool needSoftwareAdjustment;
} LadybugImageHeader;

typedef struct LadybugImageBorder {
    unsigned int uiTopRows;
    unsigned int uiBottomRows;
    unsigned int uiLeftCols;
    unsigned int uiRightCols;
} LadybugImageBorder;

typedef struct LadybugImage {
    unsigned int uiCols; /* the useful image, inside the border */
    unsigned int uiRows;
    LadybugImageBorder imageBorder;
    unsigned int uiFullCols; /* uiCols plus the left and right border */
    unsigned int uiFullRows;
    LadybugDataFormat dataFormat;
    LadybugResolution resolution;
    LadybugTimestamp timeStamp;
    LadybugImageInfo imageInfo;
    LadybugImageHeader imageHeader;
    unsigned char *pData;
    bool bStippled;
    LadybugStippledFormat stippledFormat; /* of the full image's top-left pixel */
    unsigned int uiDataSizeBytes;
    unsigned int uiBufferIndex;
    unsigned int ulReserved[3];
} LadybugImage;

typedef struct LadybugImageMetaData {
    unsigned char ucGPSHour;
    unsigned char ucGPSMinute;
    unsigned char ucGPSSecond;
    unsigned short wGPSSubSecond;
    unsigned char ucGPSDay;
    unsigned char ucGPSMonth;
    unsigned short wGPSYear;
    double dGPSLatitude;
    double dGPSLongitude;
    double dGPSAltitude;
    double dGPSGroundSpeed;
    unsigned int ulReserved[50];
} LadybugImageMetaData;

/* What ladybugRenderOffScreenImage returns: pData points into the library's own buffer. */
typedef struct LadybugProcessedImage {
    unsigned int uiCols;
    unsigned int uiRows;
    unsigned char *pData;
    LadybugPixelFormat pixelFormat;
    LadybugImageMetaData metaData;
    unsigned int ulReserved;
} LadybugProcessedImage;

typedef struct LadybugCameraInfo {
    LadybugSerialNumber serialBase;
    LadybugSerialNumber serialHead;
    bool bIsColourCamera;
    LadybugDeviceType deviceType;
    char pszModelName[256];
    char pszSensorInfo[256];
    char pszVendorName[256];
    int iDCAMVer;
    int iBusNum;
    int iNodeNum;
    LadybugBusSpeed maxBusSpeed;
    LadybugInterfaceType interfaceType;
} LadybugCameraInfo;

const char *ladybugErrorToString(const LadybugError error);
LadybugError ladybugCreateContext(LadybugContext *pcontext);
LadybugError ladybugDestroyContext(LadybugContext *pcontext);
LadybugError ladybugBusEnumerateCameras(LadybugContext context, LadybugCameraInfo *parInfo, unsigned int *puiSize);
LadybugError ladybugInitializeFromSerialNumber(LadybugContext context, LadybugSerialNumber serialNumber);
LadybugError ladybugInitializeFromIndex(LadybugContext context, unsigned int ulDevice);
LadybugError ladybugStart(LadybugContext context, LadybugDataFormat format);
LadybugError ladybugStop(LadybugContext context);
LadybugError ladybugSetGrabTimeout(LadybugContext context, unsigned int uiTimeout);
LadybugError ladybugGrabImage(LadybugContext context, LadybugImage *pImage);
LadybugError ladybugGetColorTileFormat(LadybugContext context, LadybugStippledFormat *pFormat);
LadybugError ladybugGetAbsProperty(LadybugContext context, LadybugProperty property, float *pfValue);
LadybugError ladybugSetColorProcessingMethod(LadybugContext context, LadybugColorProcessingMethod method);
LadybugError ladybugConvertImage(LadybugContext context, const LadybugImage *pImage, unsigned char **arpDestBuffers,
                                 LadybugPixelFormat pixelFormat);

#ifdef __cplusplus
}
#endif

#endif
