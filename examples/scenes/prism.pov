// checks: prism with every spline (linear with a hole, quadratic, cubic, Bezier) and a conic sweep, turned, scaled and moved, with shadows
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0, 9, -9> look_at <0, 0, 0> right x*image_width/image_height angle 50 }
light_source { <-10, 20, -15> color rgb 1 }
light_source { <10, 10, -5> color rgb 0.4 }
plane { y, -0.01 pigment { rgb 0.6 } }
prism { linear_spline 0, 1, 10, <0,0>, <2,0>, <2,2>, <0,2>, <0,0>, <0.5,0.5>, <1.5,0.5>, <1.5,1.5>, <0.5,1.5>, <0.5,0.5>
  rotate 20*y translate <-4, 0, 1> pigment { rgb <1, 0.3, 0.2> } }
prism { quadratic_spline 0, 0.8, 12, <1,-1>, <0,0>, <2,0>, <2,2>, <0,2>, <0,0>, <0.7,0.3>, <0.4,0.4>, <1.6,0.4>, <1.6,1.6>, <0.4,1.6>, <0.4,0.4>
  translate <-1, 0, 1> pigment { rgb <0.2, 0.8, 0.3> } }
prism { cubic_spline 0, 1.2, 8, <0,-1>, <0,0>, <2,0>, <2,2>, <0,2>, <0,0>, <2,0>, <0,1>
  scale <1, 1, 0.8> translate <2, 0, 1> pigment { rgb <0.3, 0.4, 1> } }
prism { bezier_spline 0, 0.6, 8, <0,0>, <1,-1>, <2,1>, <2,2>, <2,2>, <1,3>, <-1,1>, <0,0>
  translate <-3, 0, -3> pigment { rgb <1, 0.9, 0.2> } }
prism { conic_sweep linear_spline 0.5, 1, 5, <1,1>, <-1,1>, <-1,-1>, <1,-1>, <1,1>
  rotate 180*x translate <1, 1.0, -2.5> scale 1.5 pigment { rgb <0.9, 0.4, 0.9> } }
