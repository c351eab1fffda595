// checks: closed cylinder (caps), open cylinder seen inside (two-sided shading), and discs
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.7> } finish { ambient 0.05 diffuse 0.7 } }
cylinder { <-1.3, 0, 0>, <-0.7, 1.4, 0.2>, 0.35 pigment { rgb <0.3, 0.7, 0.3> } finish { ambient 0.1 diffuse 0.8 } }
cylinder { <0.1, 0.5, -0.6>, <1.1, 0.9, 0.5>, 0.45 open pigment { rgb <0.8, 0.4, 0.7> } finish { ambient 0 diffuse 0.8 } }
disc { <0.2, 1.5, 1.0>, <0.3, 0.2, -1>, 0.5 pigment { rgb <0.9, 0.8, 0.3> } finish { ambient 0.1 diffuse 0.8 } }
disc { <1.5, 0.3, -0.9>, <0, 1, 0>, 0.3 pigment { rgb <0.9, 0.2, 0.2> } finish { ambient 0.1 diffuse 0.8 } }
