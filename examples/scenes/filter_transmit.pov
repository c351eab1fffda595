// checks: filter vs transmit (colour of the light passing), filtered shadows, back faces lit through the front
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.65> } finish { ambient 0.1 diffuse 0.6 } }
sphere { <-0.9, 0.7, 0>, 0.65 pigment { rgbf <0.9, 0.3, 0.2, 0.7> } finish { ambient 0.1 diffuse 0.6 } }
sphere { <0.7, 0.7, 0.1>, 0.65 pigment { rgbt <0.2, 0.4, 0.9, 0.6> } finish { ambient 0.1 diffuse 0.6 } }
box { <-0.3, 0, 1.2>, <0.3, 1.6, 1.5> pigment { rgb <0.9, 0.9, 0.2> } finish { ambient 0.1 diffuse 0.8 } }
