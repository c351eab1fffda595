// Whitted's classic: a glass sphere and a mirror sphere over a checker floor (the speed benchmark).
// Every setting the benchmarks sweep is in global_settings; the rest is fixed.
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0, 1.6, -5.5> look_at <0, 0.8, 0> right x*image_width/image_height angle 55 }
background { rgb <0.45, 0.6, 0.85> }
light_source { <-6, 10, -8> color rgb 1 }
plane { y, 0
  pigment { checker rgb <0.9, 0.9, 0.85>, rgb <0.75, 0.12, 0.1> }
  finish { ambient 0.1 diffuse 0.8 } }
// glass: clear, Fresnel reflection, conserve_energy
sphere { <-0.9, 1.0, -0.6>, 1.0
  pigment { rgbf <1, 1, 1, 1> }
  finish { ambient 0 diffuse 0 phong 0.8 phong_size 80 reflection { 0, 1 fresnel on } conserve_energy }
  interior { ior 1.5 } }
// mirror
sphere { <1.3, 0.9, 1.2>, 0.9
  pigment { rgb <0.85, 0.85, 0.85> }
  finish { ambient 0 diffuse 0.05 phong 0.6 phong_size 60 reflection 0.85 } }
