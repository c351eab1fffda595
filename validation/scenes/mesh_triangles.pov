// checks: triangle mesh (pyramid), a flat triangle and smooth triangles (interpolated normals)
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.7> } finish { ambient 0.05 diffuse 0.7 } }
mesh { triangle { <-1.6, 0, -0.4>, <-0.6, 0, -0.4>, <-1.1, 1.2, 0> } triangle { <-0.6, 0, -0.4>, <-0.6, 0, 0.4>, <-1.1, 1.2, 0> } triangle { <-1.6, 0, 0.4>, <-1.6, 0, -0.4>, <-1.1, 1.2, 0> } pigment { rgb <0.9, 0.7, 0.3> } finish { ambient 0 diffuse 0.8 } }
triangle { <-0.4, 1.3, 1.0>, <0.3, 1.9, 1.2>, <-0.2, 0.6, 1.4> pigment { rgb <0.2, 0.8, 0.5> } finish { ambient 0 diffuse 0.8 } }
mesh { smooth_triangle { <0, 0.2, 0>, <-0.6, 0, -0.8>, <1.2, 0.2, 0>, <0.6, 0, -0.8>, <0, 1.4, 0.3>, <-0.6, 0, -0.8> } smooth_triangle { <1.2, 0.2, 0>, <0.6, 0, -0.8>, <1.2, 1.4, 0.3>, <0.6, 0, -0.8>, <0, 1.4, 0.3>, <-0.6, 0, -0.8> } pigment { rgb <0.3, 0.6, 0.9> } finish { ambient 0 diffuse 0.8 } }
