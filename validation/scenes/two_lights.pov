// checks: two coloured parallel lights: additive diffuse, two shadows, grazing N.L cut-off
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 40, -20> color rgb <0.9, 0.5, 0.3> parallel point_at <0, 0, 0> }
light_source { <25, 30, -10> color rgb <0.2, 0.4, 0.8> parallel point_at <0, 0, 0> }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.7> } finish { ambient 0 diffuse 0.8 } }
sphere { <-0.7, 0.6, 0>, 0.6 pigment { rgb <0.9, 0.9, 0.9> } finish { ambient 0 diffuse 0.9 } }
box { <0.3, 0, -0.4>, <1.3, 1.0, 0.5> pigment { rgb <0.6, 0.8, 0.5> } finish { ambient 0 diffuse 0.9 } }
