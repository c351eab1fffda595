// checks: finish brilliance (|N.L|^brilliance) at 0.5, 1, 4
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.65> } finish { ambient 0.1 diffuse 0.6 } }
sphere { <-1.1, 0.5, 0>, 0.5 pigment { rgb <0.8, 0.6, 0.3> } finish { ambient 0.05 diffuse 0.8 brilliance 0.5 } }
sphere { <0, 0.5, 0>, 0.5 pigment { rgb <0.8, 0.6, 0.3> } finish { ambient 0.05 diffuse 0.8 } }
sphere { <1.1, 0.5, 0>, 0.5 pigment { rgb <0.8, 0.6, 0.3> } finish { ambient 0.05 diffuse 0.8 brilliance 4 } }
