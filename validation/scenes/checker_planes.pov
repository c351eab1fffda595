// checks: checker pigments on three axis-aligned planes with scaled and translated patterns
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { checker rgb <0.9, 0.9, 0.85>, rgb <0.1, 0.2, 0.4> scale 0.7 translate <0.2, 0, 0.1> } finish { ambient 0.05 diffuse 0.7 } }
plane { x, -2.2 pigment { checker rgb <0.8, 0.3, 0.2>, rgb <0.9, 0.8, 0.3> scale 0.45 } finish { ambient 0.1 diffuse 0.7 } }
plane { -z, -3 pigment { checker rgb <0.3, 0.8, 0.4>, rgb <0.2, 0.2, 0.2> scale <0.6, 0.3, 1> translate <0.05, 0.1, 0> } finish { ambient 0.2 diffuse 0.6 } }
