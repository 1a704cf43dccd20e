#pragma once
/// \file render_scene.h
/// What `fascicle render` draws, independent of OpenGL: a scene of translucent lit triangles and
/// opaque coloured lines, the perceptual colour map that colours a fibre from its origin to its
/// insertion, the scenes of a muscle with its fibres and of a fibre template, and the cameras of
/// N views around the scene's principal (long) axis, framed on its bounding box. The GL side is
/// render_view.h; PNG files are render_png.h.

#include "geometry/mesh.h"
#include "springs/fibre_template.h"

#include <array>
#include <cstdint>
#include <string>
#include <vector>

namespace fascicle::shaders {

/// A linear colour with opacity, each channel in [0,1] (sRGB-encoded values, as written to PNG).
struct Rgba {
  float r = 0, g = 0, b = 0, a = 1;
};

/// An 8-bit RGB picture, rows top to bottom, 3 bytes per pixel (R, G, B).
struct Image {
  int width = 0, height = 0;
  std::vector<std::uint8_t> rgb;  ///< width * height * 3 bytes
  /// Pixel (x, y), y = 0 the top row (no bounds check).
  std::array<std::uint8_t, 3> pixel(int x, int y) const {
    const std::size_t i = (static_cast<std::size_t>(y) * width + x) * 3;
    return {rgb[i], rgb[i + 1], rgb[i + 2]};
  }
};

/// One polyline drawn as a screen-space ribbon of `width_px` pixels, one colour per point
/// (interpolated along each segment).
struct SceneLine {
  std::vector<Vec3> points;   ///< at least 2
  std::vector<Rgba> colours;  ///< one per point
  float width_px = 3.0f;      ///< ribbon width at the default 800x600 view, pixels
};

/// Everything drawn in one picture. Surfaces are translucent (sorted back to front per view and
/// blended over the opaque lines); lines are opaque.
struct RenderScene {
  std::vector<Vec3> surface_points;         ///< surface vertices (any length unit)
  std::vector<Triangle> surface_triangles;  ///< indices into surface_points
  std::vector<Rgba> triangle_colours;       ///< one per triangle (alpha = opacity facing the viewer)
  std::vector<SceneLine> lines;             ///< opaque polylines
  /// The axis the views turn around (need not be unit); zero = principal_axis() of the scene.
  Vec3 axis = Vec3::Zero();
  /// Where "origin" lies along the axis: when non-zero, the axis is turned so that it points
  /// from this point towards axis_insertion (fibres run left to right in muscle pictures).
  Vec3 axis_origin = Vec3::Zero(), axis_insertion = Vec3::Zero();
  bool has_axis_ends = false;  ///< true when axis_origin / axis_insertion are set
};

/// The perceptual colour map of fibres: viridis (van der Walt & Smith 2015, the matplotlib
/// default: uniform in CAM02-UCS lightness, readable in grey and by colour-blind viewers),
/// linearly interpolated between 10 published samples. t in [0,1] (clamped): 0 = dark purple
/// (origin), 1 = yellow (insertion). Opaque.
Rgba fibre_colour(double t);

/// Hue of an 8-bit RGB colour in degrees [0, 360) (HSV hexcone); 0 for greys. For tests and
/// checks of the colour ramp.
double hue_degrees(std::uint8_t r, std::uint8_t g, std::uint8_t b);

/// The colour of the muscle surface (a light flesh tone, translucent).
Rgba muscle_colour();

/// The colours of the attachment areas, opaque: origin red, insertion green (the template
/// pictures draw their areas in these hues, translucent).
Rgba origin_colour();
Rgba insertion_colour();

/// Appends a marker for each of `points` (landmarks): three lines of half-length `size` (scene
/// units) through it along x, y and z, in `colour`, `width_px` wide at the default view.
void add_markers(RenderScene& scene, const std::vector<Vec3>& points, const Rgba& colour, double size,
                 float width_px = 3.0f);

/// Appends `lines` to the scene, each coloured along its arc length by fibre_colour (t = 0 at
/// the first point, the origin, t = 1 at the last, the insertion; index fraction when a line
/// has zero length). Lines with fewer than 2 points are skipped. Sets the axis ends to the mean
/// first and mean last point when there is at least one line.
void add_fibres(RenderScene& scene, const Polylines& lines, float width_px = 3.0f);

/// A scene of a muscle surface (a polygon soup as read: polygons fan-triangulated, need not be
/// manifold or oriented), translucent in muscle_colour(), with `fibres` (may be null) coloured
/// from origin to insertion. Throws InputError(file_empty) naming `name` when the soup has no
/// polygon with 3 or more corners.
RenderScene muscle_scene(const PolygonSoup& soup, const Polylines* fibres, const std::string& name);

/// A scene of a fibre template (fibre_template.h) in its unit cube: the cube's 12 edges as dark
/// lines, the origin area as translucent red rectangles, the insertion area as translucent
/// green ones, and nr x ns fibres sampled at `points` points each (template_point), coloured by
/// fibre_colour. The axis is z (rectus: z as well). Throws OptionError when nr, ns < 2 or
/// points < 2.
RenderScene template_scene(springs::TemplateKind kind, int nr = 6, int ns = 3, int points = 40);

/// Principal axis of the scene: the eigenvector of the largest eigenvalue of the covariance of
/// the surface (triangles weighted by area, at their centroids), or of the line points when
/// there is no surface area. Unit length. Throws Error(internal) for an empty scene.
Vec3 principal_axis(const RenderScene& scene);

/// Axis-aligned bounding box of every surface and line point.
struct SceneBounds {
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
};
/// Bounds of the scene. Throws Error(internal) for an empty scene.
SceneBounds scene_bounds(const RenderScene& scene);

/// An orthographic camera: screen axes `right`, `up` and `forward` (towards the scene), unit and
/// right-handed, the point of the scene at the picture's centre, and the half extents of the
/// picture in scene units.
struct Camera {
  Vec3 right, up, forward, centre;
  double half_width = 1, half_height = 1;  ///< scene units at the picture's edge
  double near = -1, far = 1;               ///< depth range along forward, from centre
};

/// Options of view_cameras.
struct ViewLayout {
  int views = 4;                  ///< cameras, evenly spaced around the axis (default 4)
  double aspect = 800.0 / 600.0;  ///< width / height of one view (default 4:3)
  double elevation_deg = 0;       ///< tilt of the viewing direction out of the plane normal to the
                                  ///< axis, towards the axis (default 0)
  double azimuth_deg = 0;         ///< turn of the first view around the axis (default 0)
  bool axis_up = false;           ///< axis points up on screen (default false: to the right)
  double margin = 0.06;           ///< blank border, fraction of the half extents (default 0.06)
  /// Throws OptionError naming the field.
  void validate() const;
};

/// The cameras of N views around the scene's axis (scene.axis, else principal_axis), turned so
/// that the axis points from axis_origin to axis_insertion when those are set. Every view has
/// the same scale, the largest needed to fit the scene into any view: every point is projected
/// onto the view's screen axes (the scene's bounding box in view coordinates) and the widest
/// extent plus the margin sets the scale, so sizes compare across views; each view is centred
/// on the middle of its projected extent. Throws Error(internal) for an empty scene and
/// OptionError for a bad layout.
std::vector<Camera> view_cameras(const RenderScene& scene, const ViewLayout& layout);

}  // namespace fascicle::shaders
