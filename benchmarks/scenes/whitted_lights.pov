// A Whitted scene nobody tuned for (tinyraytracer's, in POV-Ray's terms): four spheres with phong
// highlights (ivory, glass, red rubber, a mirror), a checker box floor, three point lights,
// max_trace_level 5 (the speed benchmark's multi-light case).
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0, 0, 0> look_at <0, 0, 1> right x*image_width/image_height angle 60 }
background { rgb <0.2, 0.7, 0.8> }
light_source { <-20, 20, -20> color rgb 0.75 }
light_source { <30, 50, 25> color rgb 0.9 }
light_source { <30, 20, -30> color rgb 0.85 }
box { <-10, -4.1, 10>, <10, -4, 30>
  pigment { checker rgb <0.3, 0.3, 0.3>, rgb <0.3, 0.2, 0.1> scale 2 }
  finish { ambient 0.1 diffuse 0.9 } }
// ivory
sphere { <-3, 0, 16>, 2
  pigment { rgb <0.4, 0.4, 0.3> }
  finish { ambient 0 diffuse 0.6 phong 0.3 phong_size 50 reflection 0.1 } }
// glass
sphere { <-1, -1.5, 12>, 2
  pigment { rgbf <1, 1, 1, 0.8> }
  finish { ambient 0 diffuse 0 phong 0.5 phong_size 125 reflection 0.1 }
  interior { ior 1.5 } }
// red rubber
sphere { <1.5, -0.5, 18>, 3
  pigment { rgb <0.3, 0.1, 0.1> }
  finish { ambient 0 diffuse 0.9 phong 0.1 phong_size 10 } }
// mirror
sphere { <7, 5, 18>, 4
  pigment { rgb 1 }
  finish { ambient 0 diffuse 0 phong 10 phong_size 1425 reflection 0.8 } }
