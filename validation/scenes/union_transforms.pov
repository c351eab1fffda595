// checks: union of spheres and boxes moved as one (rotate, uniform scale, translate) with the parent texture
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.7> } finish { ambient 0.05 diffuse 0.7 } }
union { sphere { <0, 0.5, 0>, 0.5 } box { <0.3, 0, -0.3>, <1.0, 0.7, 0.3> } sphere { <1.2, 0.3, 0>, 0.3 pigment { rgb <0.2, 0.8, 0.3> } } rotate <0, -40, 0> scale 1.1 translate <-0.6, 0, 0> pigment { rgb <0.85, 0.4, 0.3> } finish { ambient 0.1 diffuse 0.8 } }
