// checks: checker (scaled), gradient with a color_map (ramp, 5-channel interpolation), pattern transforms, the built-in maps of radial and marble
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { checker rgb <0.9, 0.9, 0.85>, rgb <0.1, 0.3, 0.2> scale 0.7 rotate <0, 20, 0> } finish { ambient 0.1 diffuse 0.6 } }
sphere { <-0.8, 0.7, 0>, 0.7 pigment { gradient y color_map { [0 rgb <1, 0, 0>] [0.5 rgb <1, 1, 0>] [1 rgb <0, 0, 1>] } scale 0.5 } finish { ambient 0.1 diffuse 0.8 } }
box { <0.2, 0, -0.5>, <1.4, 1.2, 0.5> pigment { gradient <1, 1, 0> color_map { [0.2 rgb <0.1, 0.8, 0.3>] [0.8 rgb <0.9, 0.2, 0.7>] } } finish { ambient 0.1 diffuse 0.8 } }
sphere { <-1.9, 0.45, -0.9>, 0.45 pigment { radial frequency 3 } finish { ambient 0.3 diffuse 0.6 } }
sphere { <1.9, 0.45, -0.9>, 0.45 pigment { marble scale 0.3 rotate 30*z } finish { ambient 0.3 diffuse 0.6 } }
