// checks: lathe with every spline (linear tube, quadratic, cubic, Bezier), moved, with highlights and shadows
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 4, -9> look_at <0, 1, 0> right x*image_width/image_height angle 50 }
light_source { <-8, 15, -12> color rgb 1 }
light_source { <10, 8, -4> color rgb 0.4 }
plane { y, 0 pigment { checker rgb 0.8, rgb 0.3 } }
lathe { linear_spline 5, <1, 0>, <1.5, 0>, <1.5, 2>, <1, 2>, <1, 0> translate <-3.5, 0, 1> pigment { rgb <1, 0.3, 0.2> } }
lathe { quadratic_spline 6, <0, 0>, <1, 0>, <1.2, 1>, <0.5, 2>, <0.8, 2.5>, <0, 3> translate <-0.5, 0, 1> pigment { rgb <0.2, 0.8, 0.3> } finish { phong 0.6 } }
lathe { cubic_spline 8, <0, -0.5>, <0, 0>, <1, 0.3>, <0.4, 1>, <0.9, 1.8>, <0.2, 2.2>, <0, 2.4>, <0, 3> translate <2, 0, 1> pigment { rgb <0.3, 0.4, 1> } }
lathe { bezier_spline 8, <0, 0>, <1.2, 0>, <1.2, 0.6>, <0.5, 1>, <0.5, 1>, <1, 1.3>, <0.3, 1.6>, <0, 1.6> translate <4.2, 0, -1> pigment { rgb <1, 0.9, 0.2> } }
