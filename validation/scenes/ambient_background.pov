// checks: ambient x ambient_light as self-emission (also seen in shadow) and a background colour seen by escaping rays
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 ambient_light rgb <0.9, 1.0, 1.2> }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
background { rgb <0.15, 0.25, 0.45> }
plane { y, 0 pigment { rgb <0.6, 0.6, 0.6> } finish { ambient 0.2 diffuse 0.6 } }
sphere { <-0.8, 0.6, 0>, 0.6 pigment { rgb <0.3, 0.7, 0.9> } finish { ambient 1 diffuse 0 } }
sphere { <0.8, 0.6, 0.2>, 0.6 pigment { rgb <0.9, 0.5, 0.2> } finish { ambient 0.3 diffuse 0.6 } }
