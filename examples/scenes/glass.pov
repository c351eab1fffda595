// checks: glass refraction with Fresnel, conserve_energy, total internal reflection, no shadow through transmit 1
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 10 }
camera { location <0.13, 1.63, -5.11> look_at <0.02, 0.61, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { checker rgb <0.9, 0.9, 0.85>, rgb <0.2, 0.25, 0.3> } finish { ambient 0.15 diffuse 0.6 } }
plane { -z, -3 pigment { checker rgb <0.9, 0.3, 0.1>, rgb <0.1, 0.3, 0.9> scale 0.5 } finish { ambient 1 diffuse 0 } }
sphere { <-0.8, 0.7, 0>, 0.7 pigment { rgbt <1, 1, 1, 1> } finish { ambient 0 diffuse 0 reflection { 0, 1 fresnel on } conserve_energy } interior { ior 1.5 } }
box { <-0.5, 0, -0.5>, <0.5, 1, 0.5> rotate <0, 30, 0> translate <0.9, 0, 0.2> pigment { rgbf <1, 1, 1, 1> } finish { ambient 0 diffuse 0 reflection { 0, 1 fresnel on } conserve_energy } interior { ior 1.6 } }
