// checks: Lambert sphere on a checker ground under one parallel light: camera, irradiance mapping, shadow
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { checker rgb <0.8, 0.8, 0.75>, rgb <0.2, 0.3, 0.2> } finish { ambient 0 diffuse 0.6 } }
sphere { <0, 0.8, 0>, 0.8 pigment { rgb <0.8, 0.3, 0.2> } finish { ambient 0 diffuse 0.9 } }
