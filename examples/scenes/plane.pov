// checks: planes (infinite, horizon), checker pigment on a plane, background colour
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
background { rgb <0.2, 0.3, 0.5> }
plane { y, 0 pigment { checker rgb <0.9, 0.9, 0.85>, rgb <0.15, 0.2, 0.15> } finish { ambient 0.1 diffuse 0.7 } }
plane { <1, 0, -0.3>, 2.5 pigment { rgb <0.6, 0.4, 0.2> } finish { ambient 0.2 diffuse 0.5 } }
