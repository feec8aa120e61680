/* rigd's stand-in for FLIR's ladybuggeom.h (tests only): the geometry functions rigd calls, as declared there. */
#ifndef RIGD_FAKE_LADYBUGGEOM_H
#define RIGD_FAKE_LADYBUGGEOM_H

#include "ladybug.h"

#ifdef __cplusplus
extern "C" {
#endif

LadybugError ladybugLoadConfig(LadybugContext context, const char *pszPath);
LadybugError ladybugGetCameraUnitFocalLength(LadybugContext context, unsigned int uiCamera, double *pdFocalLength);
LadybugError ladybugGetCameraUnitImageCenter(LadybugContext context, unsigned int uiCamera, double *pdCenterX,
                                             double *pdCenterY);
LadybugError ladybugGetCameraUnitExtrinsics(LadybugContext context, unsigned int uiCamera, double ardEulerZYX[6]);
LadybugError ladybugUnrectifyPixel(LadybugContext context, unsigned int uiCamera, double dRectifiedRow,
                                   double dRectifiedCol, double *pdDistortedRow, double *pdDistortedCol);
LadybugError ladybugRectifyPixel(LadybugContext context, unsigned int uiCamera, double dDistortedRow,
                                 double dDistortedCol, double *pdRectifiedRow, double *pdRectifiedCol);

#ifdef __cplusplus
}
#endif

#endif
