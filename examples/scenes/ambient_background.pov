// checks: ambient with ambient_light, emission, background (not a light), unlit glowing object
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 ambient_light rgb <0.8, 0.9, 1.2> }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
background { rgb <0.4, 0.2, 0.1> }
plane { y, 0 pigment { rgb <0.5, 0.5, 0.5> } finish { ambient 0.3 diffuse 0.5 } }
sphere { <-0.8, 0.6, 0>, 0.6 pigment { rgb <0.3, 0.7, 0.9> } finish { ambient 1 diffuse 0 } }
sphere { <0.8, 0.6, 0>, 0.6 pigment { rgb <0.9, 0.5, 0.2> } finish { ambient 0.2 emission 0.3 diffuse 0.5 } }
