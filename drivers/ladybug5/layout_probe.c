/*
 * Prints, as YAML, the numbers rigd's ctypes binding (drivers/ladybug5/sdk.py) needs from the installed
 * Ladybug SDK's ladybug.h: struct offsets and sizes, and the values of the enum members it uses. FLIR's
 * header is the only authority on these and they change between SDK versions, so they are measured
 * here instead of being written into the Python code.
 *
 *   rigd camera sdk-layout --include /usr/include/ladybug --out ladybug_layout.yaml
 *
 * compiles this file with the system compiler (C or C++) and runs it.
 */
#include <stddef.h>
#include <stdio.h>

#include <ladybug.h>

#define FIELD(name, type, member) \
    printf("  %s: [%lu, %lu]\n", name, (unsigned long)offsetof(type, member), \
           (unsigned long)sizeof(((type *)0)->member))
#define VALUE(name, member) printf("  %s: %ld\n", name, (long)(member))

int main(void)
{
    printf("image_size: %lu\n", (unsigned long)sizeof(LadybugImage));
    printf("image_fields:  # name: [offset, bytes]\n");
    FIELD("cols", LadybugImage, uiCols);
    FIELD("rows", LadybugImage, uiRows);
    FIELD("cycle_seconds", LadybugImage, timeStamp.ulCycleSeconds);
    FIELD("cycle_count", LadybugImage, timeStamp.ulCycleCount);
    FIELD("embedded_seconds", LadybugImage, imageInfo.ulTimeSeconds);
    FIELD("embedded_microseconds", LadybugImage, imageInfo.ulTimeMicroSeconds);
    FIELD("sequence_id", LadybugImage, imageInfo.ulSequenceId);
    FIELD("data_format", LadybugImage, dataFormat);
    FIELD("data", LadybugImage, pData);
    FIELD("data_size", LadybugImage, uiDataSizeBytes);
    printf("camera_info_size: %lu\n", (unsigned long)sizeof(LadybugCameraInfo));
    printf("camera_info_fields:\n");
    FIELD("serial_head", LadybugCameraInfo, serialHead);
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
    printf("formats:\n");
    VALUE("RAW8", LADYBUG_DATAFORMAT_RAW8);
    VALUE("COLOR_SEP_JPEG8", LADYBUG_DATAFORMAT_COLOR_SEP_JPEG8);
    printf("properties:\n");
    VALUE("SHUTTER", LADYBUG_SHUTTER);
    VALUE("GAIN", LADYBUG_GAIN);
    return 0;
}
