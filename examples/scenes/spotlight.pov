// checks: spotlight cone (radius, falloff, tightness) on a plane
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 3.63, -5.11> look_at <0.02, 0, 0> right x*image_width/image_height angle 50 }
light_source { <0, 4, 0> color rgb <1, 0.9, 0.7> spotlight point_at <-1, 0, 0.5> radius 15 falloff 30 tightness 5 }
light_source { <2, 3, -1> color rgb <0.5, 0.7, 1> spotlight point_at <1.2, 0, 0> radius 10 falloff 20 }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.65> } finish { ambient 0.1 diffuse 0.6 } }
sphere { <-0.7, 0.4, 0.3>, 0.4 pigment { rgb 0.9 } finish { ambient 0.05 diffuse 0.8 } }
