// checks: the same mirrors cut at max_trace_level 3: recursion depth counting (primary + 2 bounces)
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 3 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
background { rgb <0.3, 0.2, 0.1> }
plane { y, 0 pigment { checker rgb <0.8, 0.8, 0.75>, rgb <0.2, 0.3, 0.2> } finish { ambient 0.1 diffuse 0.6 } }
box { <-2.1, 0, -3>, <-2.0, 2.5, 3> pigment { rgb 0 } finish { ambient 0 diffuse 0 reflection rgb 0.9 } }
box { <2.0, 0, -3>, <2.1, 2.5, 3> rotate <0, 0, 3> pigment { rgb 0 } finish { ambient 0 diffuse 0 reflection rgb <0.85, 0.9, 0.95> } }
sphere { <0.3, 0.5, 0.5>, 0.5 pigment { rgb <0.9, 0.3, 0.2> } finish { ambient 0.1 diffuse 0.8 } }
