/* rigd's stand-in for FLIR's ladybugrenderer.h (tests only): the output image types (the real bit values) and
 * the renderer functions rigd calls: the off-screen size (which also sets the rectified resolution) and the
 * panorama rendering (configure, update the six textures, render off screen). FLIR's header gives the pixel
 * formats default arguments (C++); they are left out here. */
#ifndef RIGD_FAKE_LADYBUGRENDERER_H
#define RIGD_FAKE_LADYBUGRENDERER_H

#include "ladybug.h"
#include "ladybuggeom.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef enum {
    LADYBUG_RAW_CAM0 = (0x1 << 0), LADYBUG_RAW_CAM1 = (0x1 << 1), LADYBUG_RAW_CAM2 = (0x1 << 2),
    LADYBUG_RAW_CAM3 = (0x1 << 3), LADYBUG_RAW_CAM4 = (0x1 << 4), LADYBUG_RAW_CAM5 = (0x1 << 5),
    LADYBUG_ALL_RAW_IMAGES = 0x0000003F,
    LADYBUG_RECTIFIED_CAM0 = (0x1 << 6), LADYBUG_RECTIFIED_CAM1 = (0x1 << 7), LADYBUG_RECTIFIED_CAM2 = (0x1 << 8),
    LADYBUG_RECTIFIED_CAM3 = (0x1 << 9), LADYBUG_RECTIFIED_CAM4 = (0x1 << 10), LADYBUG_RECTIFIED_CAM5 = (0x1 << 11),
    LADYBUG_ALL_RECTIFIED_IMAGES = 0x00000FC0,
    LADYBUG_PANORAMIC = (0x1 << 12),
    LADYBUG_DOME = (0x1 << 13),
    LADYBUG_SPHERICAL = (0x1 << 14),
    LADYBUG_ALL_CAMERAS_VIEW = (0x1 << 15),
    LADYBUG_ALL_OUTPUT_IMAGE = 0x7FFFFFFF
} LadybugOutputImage;

LadybugError ladybugSetOffScreenImageSize(LadybugContext context, LadybugOutputImage imageType, unsigned int uiWidth,
                                          unsigned int uiHeight);
LadybugError ladybugConfigureOutputImages(LadybugContext context, unsigned int uiImageTypes);
LadybugError ladybugUpdateTextures(LadybugContext context, unsigned int uiCameras, const unsigned char **arpBGRABuffers,
                                   LadybugPixelFormat pixelFormat);
LadybugError ladybugRenderOffScreenImage(LadybugContext context, LadybugOutputImage imageType,
                                         LadybugPixelFormat pixelFormat, LadybugProcessedImage *pImage);

#ifdef __cplusplus
}
#endif

#endif
