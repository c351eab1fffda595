// checks: CSG intersection and difference (cut faces take the subtracted object's texture)
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.65> } finish { ambient 0.1 diffuse 0.6 } }
intersection { box { <-0.6, 0, -0.6>, <0.6, 1.2, 0.6> } sphere { <0, 0.6, 0>, 0.8 } rotate <0, 30, 0> translate <-0.9, 0, 0.2> pigment { rgb <0.8, 0.3, 0.3> } finish { ambient 0.1 diffuse 0.8 } }
difference { box { <-0.6, 0, -0.6>, <0.6, 1.2, 0.6> pigment { rgb <0.3, 0.7, 0.3> } } sphere { <-0.3, 0.9, -0.4>, 0.6 pigment { rgb <0.9, 0.8, 0.2> } } cylinder { <0, 0.6, -1>, <0, 0.6, 1>, 0.2 } rotate <0, -25, 0> translate <0.9, 0, 0.2> pigment { rgb <0.2, 0.3, 0.9> } finish { ambient 0.1 diffuse 0.8 } }
