// checks: spheres under uniform scale and translation (radius and centre through the transform), several shadows
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { checker rgb <0.85, 0.85, 0.8>, rgb <0.35, 0.35, 0.45> scale 0.8 } finish { ambient 0 diffuse 0.7 } }
sphere { <0, 1, 0>, 1 scale 0.55 translate <-1.1, 0, 0.2> pigment { rgb <0.9, 0.3, 0.3> } finish { ambient 0 diffuse 0.9 } }
sphere { <0, 0, 0>, 1 scale 0.35 rotate <10, 20, 30> translate <0, 0.35, -0.4> pigment { rgb <0.3, 0.9, 0.3> } finish { ambient 0 diffuse 0.9 } }
sphere { <0.3, 0.5, 0.2>, 0.5 scale 1.3 translate <0.6, 0, 0.6> pigment { rgb <0.3, 0.4, 0.9> } finish { ambient 0 diffuse 0.9 } }
