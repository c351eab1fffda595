// checks: polygon with a hole (even-odd rule, sub-polygons closed by repeating the first point)
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.65> } finish { ambient 0.1 diffuse 0.6 } }
polygon { 10, <-1, 0>, <1, 0>, <1, 1.4>, <-1, 1.4>, <-1, 0>, <-0.4, 0.3>, <0.5, 0.3>, <0.5, 1.0>, <-0.4, 1.0>, <-0.4, 0.3> rotate <0, -20, 0> translate <0, 0.05, 0> pigment { rgb <0.9, 0.4, 0.1> } finish { ambient 0.15 diffuse 0.8 } }
