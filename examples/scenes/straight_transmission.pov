// checks: ior-1 (straight) transmission through nested filter shells does not use up trace levels (max_trace_level 2)
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 2 }
camera { location <0, 0.5, -6> look_at <0, 0.3, 0> right x*image_width/image_height angle 45 }
light_source { <-10, 20, -15> color rgb 1 }
background { color rgb <0.8, 0.6, 0.4> }
plane { y, -2 pigment { checker rgb <0.9, 0.9, 0.9>, rgb <0.3, 0.3, 0.3> } finish { ambient 0.2 diffuse 0.6 } }
sphere { 0, 0.8 pigment { rgbf <1, 0.6, 0.6, 0.9> } finish { ambient 0 diffuse 0.1 phong 0.5 } }
sphere { 0, 1.3 pigment { rgbt <0.6, 1, 0.6, 0.8> } finish { ambient 0 diffuse 0.1 } }
sphere { 0, 1.8 pigment { rgbf <0.6, 0.6, 1, 0.9> } finish { ambient 0 diffuse 0.1 } }
