// checks: CSG union (inner surfaces kept) vs merge (inner surfaces removed), seen through transmit
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.65> } finish { ambient 0.1 diffuse 0.6 } }
union { sphere { <-0.35, 0.7, 0>, 0.5 } sphere { <0.15, 0.7, 0>, 0.5 } translate <-0.8, 0, 0> pigment { rgbt <0.9, 0.5, 0.3, 0.6> } finish { ambient 0.1 diffuse 0.7 } }
merge { sphere { <-0.25, 0.7, 0>, 0.5 } sphere { <0.25, 0.7, 0>, 0.5 } translate <0.9, 0, 0> pigment { rgbt <0.3, 0.6, 0.9, 0.6> } finish { ambient 0.1 diffuse 0.7 } }
