/*
 * Prints, as YAML, the numbers rigd's ctypes binding (drivers/ladybug5/sdk_library.py) needs from the
 * installed Ladybug SDK's headers: struct offsets and sizes (LadybugImage, LadybugCameraInfo,
 * LadybugProcessedImage, LadybugImage3d and LadybugPoint3d), and the values of the enum members it uses.
 * FLIR's headers are the only authority on these and they change between SDK versions, so they are measured
 * here instead of being written into the Python code.
 *
 *   rigd camera sdk-layout --include /usr/include/ladybug --out ladybug_layout.yaml
 *
 * compiles this file with the system compiler (C++ for FLIR's headers, which use C++ syntax) and runs it.
 * If a member does not exist in your SDK version, the compiler names it.
 */
#include <stddef.h>
#include <stdio.h>

#include <ladybug.h>
#include <ladybuggeom.h>
#include <ladybugrenderer.h>

#define FIELD(name, type, member) \
    printf("  %s: [%lu, %lu]\n", name, (unsigned long)offsetof(type, member), \
           (unsigned long)sizeof(((type *)0)->member))
#define VALUE(name, member) printf("  %s: %ld\n", name, (long)(member))

static void image_fields(void)
{
    printf("image_size: %lu\n", (unsigned long)sizeof(LadybugImage));
    printf("image_fields:  # name: [offset, bytes]\n");
    FIELD("cols", LadybugImage, uiCols);
    FIELD("rows", LadybugImage, uiRows);
    FIELD("full_cols", LadybugImage, uiFullCols);
    FIELD("full_rows", LadybugImage, uiFullRows);
    FIELD("border_top", LadybugImage, imageBorder.uiTopRows);
    FIELD("border_bottom", LadybugImage, imageBorder.uiBottomRows);
    FIELD("border_left", LadybugImage, imageBorder.uiLeftCols);
    FIELD("border_right", LadybugImage, imageBorder.uiRightCols);
    FIELD("data_format", LadybugImage, dataFormat);
    FIELD("stippled_format", LadybugImage, stippledFormat);
    FIELD("cycle_seconds", LadybugImage, timeStamp.ulCycleSeconds);
    FIELD("cycle_count", LadybugImage, timeStamp.ulCycleCount);
    FIELD("embedded_seconds", LadybugImage, imageInfo.ulTimeSeconds);
    FIELD("embedded_microseconds", LadybugImage, imageInfo.ulTimeMicroSeconds);
    FIELD("sequence_id", LadybugImage, imageInfo.ulSequenceId);
    FIELD("data", LadybugImage, pData);
    FIELD("data_size", LadybugImage, uiDataSizeBytes);
    printf("camera_info_size: %lu\n", (unsigned long)sizeof(LadybugCameraInfo));
    printf("camera_info_fields:\n");
    FIELD("serial_head", LadybugCameraInfo, serialHead);
    FIELD("model_name", LadybugCameraInfo, pszModelName);
    printf("processed_image_size: %lu\n", (unsigned long)sizeof(LadybugProcessedImage));
    printf("processed_image_fields:\n");
    FIELD("cols", LadybugProcessedImage, uiCols);
    FIELD("rows", LadybugProcessedImage, uiRows);
    FIELD("data", LadybugProcessedImage, pData);
    FIELD("pixel_format", LadybugProcessedImage, pixelFormat);
    printf("image3d_fields:\n");
    FIELD("rows", LadybugImage3d, uiRows);
    FIELD("cols", LadybugImage3d, uiCols);
    FIELD("points", LadybugImage3d, ppoints);
    printf("point3d_size: %lu\n", (unsigned long)sizeof(LadybugPoint3d));
    printf("point3d_fields:\n");
    FIELD("x", LadybugPoint3d, fX);
    FIELD("y", LadybugPoint3d, fY);
    FIELD("z", LadybugPoint3d, fZ);
}

static void enum_values(void)
{
    printf("errors:\n");
    VALUE("OK", LADYBUG_OK);
    VALUE("TIMEOUT", LADYBUG_TIMEOUT);
    VALUE("IMAGE_TOO_SMALL", LADYBUG_IMAGE_TOO_SMALL);
    VALUE("JPEG_ERROR", LADYBUG_JPEG_ERROR);
    VALUE("JPEG_HEADER_ERROR", LADYBUG_JPEG_HEADER_ERROR);
    VALUE("JPEG_INCOMPLETE_COMPRESSION", LADYBUG_JPEG_INCOMPLETE_COMPRESSION);
    VALUE("JPEG_NO_IMAGE", LADYBUG_JPEG_NO_IMAGE);
    VALUE("CORRUPTED_IMAGE_DATA", LADYBUG_CORRUPTED_IMAGE_DATA);
    VALUE("BAD_VOLTAGE", LADYBUG_BAD_VOLTAGE);
    VALUE("BAD_INTERFACE", LADYBUG_BAD_INTERFACE);
    VALUE("CALIBRATION_FILE_NOT_FOUND", LADYBUG_CALIBRATION_FILE_NOT_FOUND);
    VALUE("NEED_RECTIFY_RESOLUTION", LADYBUG_NEED_RECTIFY_RESOLUTION);
    printf("formats:\n");
    VALUE("RAW8", LADYBUG_DATAFORMAT_RAW8);
    VALUE("JPEG8", LADYBUG_DATAFORMAT_JPEG8);
    VALUE("COLOR_SEP_RAW8", LADYBUG_DATAFORMAT_COLOR_SEP_RAW8);
    VALUE("COLOR_SEP_JPEG8", LADYBUG_DATAFORMAT_COLOR_SEP_JPEG8);
    VALUE("HALF_HEIGHT_RAW8", LADYBUG_DATAFORMAT_HALF_HEIGHT_RAW8);
    VALUE("COLOR_SEP_HALF_HEIGHT_JPEG8", LADYBUG_DATAFORMAT_COLOR_SEP_HALF_HEIGHT_JPEG8);
    VALUE("RAW16", LADYBUG_DATAFORMAT_RAW16);
    VALUE("COLOR_SEP_JPEG12", LADYBUG_DATAFORMAT_COLOR_SEP_JPEG12);
    VALUE("HALF_HEIGHT_RAW16", LADYBUG_DATAFORMAT_HALF_HEIGHT_RAW16);
    VALUE("COLOR_SEP_HALF_HEIGHT_JPEG12", LADYBUG_DATAFORMAT_COLOR_SEP_HALF_HEIGHT_JPEG12);
    VALUE("RAW12", LADYBUG_DATAFORMAT_RAW12);
    VALUE("HALF_HEIGHT_RAW12", LADYBUG_DATAFORMAT_HALF_HEIGHT_RAW12);
    printf("properties:\n");
    VALUE("SHUTTER", LADYBUG_SHUTTER);
    VALUE("GAIN", LADYBUG_GAIN);
    printf("stippled:\n");
    VALUE("BGGR", LADYBUG_BGGR);
    VALUE("GBRG", LADYBUG_GBRG);
    VALUE("GRBG", LADYBUG_GRBG);
    VALUE("RGGB", LADYBUG_RGGB);
    VALUE("DEFAULT", LADYBUG_DEFAULT);
    printf("output_images:\n");
    VALUE("ALL_RECTIFIED_IMAGES", LADYBUG_ALL_RECTIFIED_IMAGES);
    VALUE("PANORAMIC", LADYBUG_PANORAMIC);
    printf("pixel_formats:\n");
    VALUE("BGR", LADYBUG_BGR);
    VALUE("BGRU", LADYBUG_BGRU);
    VALUE("BGRU16", LADYBUG_BGRU16);
    printf("color_methods:\n");
    VALUE("EDGE_SENSING", LADYBUG_EDGE_SENSING);
    VALUE("NEAREST_NEIGHBOR_FAST", LADYBUG_NEAREST_NEIGHBOR_FAST);
    VALUE("RIGOROUS", LADYBUG_RIGOROUS);
    VALUE("HQLINEAR", LADYBUG_HQLINEAR);
}

int main(void)
{
    image_fields();
    enum_values();
    return 0;
}
