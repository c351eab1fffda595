// checks: point lights (no falloff) and fade_distance/fade_power (2/(1+(d/fd)^fp)), coloured lights
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-2, 3, -2> color rgb <1, 0.8, 0.6> }
light_source { <2, 1.5, -1> color rgb <0.4, 0.6, 1> fade_distance 2 fade_power 2 }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.65> } finish { ambient 0.1 diffuse 0.6 } }
sphere { <-0.5, 0.6, 0>, 0.6 pigment { rgb <0.9, 0.9, 0.9> } finish { ambient 0.05 diffuse 0.8 } }
box { <0.4, 0, -0.3>, <1.2, 0.8, 0.5> pigment { rgb <0.8, 0.8, 0.8> } finish { ambient 0.05 diffuse 0.8 } }
