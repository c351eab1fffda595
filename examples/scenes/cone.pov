// checks: cone (frustum) closed and open, and a pointed cone
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.65> } finish { ambient 0.1 diffuse 0.6 } }
cone { <-1.1, 0, 0>, 0.6, <-1.0, 1.3, 0.1>, 0.2 pigment { rgb <0.8, 0.5, 0.2> } finish { ambient 0.1 diffuse 0.8 } }
cone { <0.2, 0, 0.3>, 0.5, <0.3, 1.5, 0.2>, 0 pigment { rgb <0.2, 0.6, 0.8> } finish { ambient 0.1 diffuse 0.8 } }
cone { <1.0, 0.6, -0.8>, 0.1, <1.6, 1.0, 0.0>, 0.45 open pigment { rgb <0.9, 0.9, 0.3> } finish { ambient 0.1 diffuse 0.8 } }
