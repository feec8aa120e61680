/* rigd's stand-in for FLIR's ladybuggeom.h (tests only): the geometry functions rigd calls, as declared there. */
#ifndef RIGD_FAKE_LADYBUGGEOM_H
#define RIGD_FAKE_LADYBUGGEOM_H

#include "ladybug.h"

#ifdef __cplusplus
extern "C" {
#endif

/* A 3D point and an "image" of them, member for member as in FLIR's ladybuggeom.h (2017). */
typedef struct LadybugPoint3d {
    float fX, fY, fZ;
    float fTheta, fPhi;
    float fCylAngle, fCylHeight;
} LadybugPoint3d;

typedef struct LadybugImage3d {
    unsigned int uiRows;
    unsigned int uiCols;
    double dRx, dRy, dRz, dTx, dTy, dTz;
    float fCylHeightMin;
    float fCylHeightMax;
    LadybugPoint3d *ppoints;
} LadybugImage3d;

LadybugError ladybugLoadConfig(LadybugContext context, const char *pszPath);
LadybugError ladybugGet3dMap(LadybugContext context, unsigned int uiCamera, unsigned int uiGridCols,
                             unsigned int uiGridRows, unsigned int uiSrcCols, unsigned int uiSrcRows,
                             bool bCenterSampling, const LadybugImage3d **ppimage);
LadybugError ladybugSet3dMapSphereSize(LadybugContext context, double dRadius);
LadybugError ladybugGet3dMapSphereSize(LadybugContext context, double *pdRadius);
LadybugError ladybugSet3dMapRotation(LadybugContext context, double dRx, double dRy, double dRz);
LadybugError ladybugGet3dMapRotation(LadybugContext context, double *pdRx, double *pdRy, double *pdRz);
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
