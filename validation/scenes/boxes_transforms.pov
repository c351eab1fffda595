// checks: boxes under rotate / non-uniform scale / translate (POV rotate order x, y, z)
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.7> } finish { ambient 0.05 diffuse 0.7 } }
box { <-0.5, 0, -0.5>, <0.5, 1, 0.5> scale <1.2, 0.8, 0.6> rotate <0, 35, 0> translate <-0.9, 0, 0.3> pigment { rgb <0.2, 0.5, 0.8> } finish { ambient 0.05 diffuse 0.85 } }
box { <0.3, 0, -0.4>, <1.3, 0.6, 0.6> rotate <20, -15, 10> translate <0.2, 0.4, 0> pigment { rgb <0.9, 0.7, 0.2> } finish { ambient 0.05 diffuse 0.85 } }
