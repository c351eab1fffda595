// checks: shadowless fill light (no shadow, no highlight) and no_shadow objects
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
light_source { <3, 2, -4> color rgb <0.3, 0.3, 0.4> shadowless }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.65> } finish { ambient 0.1 diffuse 0.6 } }
sphere { <-0.8, 0.7, 0>, 0.6 pigment { rgb <0.8, 0.5, 0.3> } finish { ambient 0.1 diffuse 0.7 phong 0.5 } }
sphere { <0.8, 0.7, 0>, 0.6 pigment { rgb <0.3, 0.8, 0.5> } finish { ambient 0.1 diffuse 0.7 } no_shadow }
