// checks: image_map (PNG decoded from sRGB) planar with the nearest pixel and with interpolate 2,
// spherical (map_type 1), cylindrical (map_type 2) and once (clear outside the unit square)
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 0.4, -7> look_at <0, 0.3, 0> right x*image_width/image_height angle 50 }
light_source { <-5, 8, -8> color rgb 1 }
background { rgb <0.2, 0.3, 0.5> }
sphere { <-1.7, 0.9, 0>, 1
  pigment { image_map { png "image_map.png" map_type 1 } rotate y*40 translate <-1.7, 0.9, 0> } }
cylinder { <1.6, -0.6, 0>, <1.6, 1.6, 0>, 0.8
  pigment { image_map { png "image_map.png" map_type 2 interpolate 2 } rotate y*70 translate <1.6, -0.3, 0> } }
box { <-0.7, -1.3, -0.5>, <0.7, 0.1, 0.5>
  pigment { image_map { png "image_map.png" interpolate 2 } scale 1.4 translate <-0.7, -1.3, 0> } }
plane { -z, -2 pigment { image_map { png "image_map.png" once } scale 2 translate <-1, 1.1, 0> } }
