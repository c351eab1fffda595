// checks: isosurface (a sphere cut by its box, whose walls are seen; a wavy sheet in a sphere; an open one showing its inside; a declared function with parameters, threshold), moved, with highlights and shadows
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 3.5, -8> look_at <0, 0.8, 0> right x*image_width/image_height angle 50 }
light_source { <-8, 15, -12> color rgb 1 }
light_source { <10, 8, -4> color rgb 0.4 }
plane { y, 0 pigment { checker rgb 0.8, rgb 0.3 } }
#declare R = 1.15;
#declare Ball = function(a, b, c, s) { sqrt(a*a + b*b + c*c) - s }
isosurface { function { Ball(x, y, z, R) } contained_by { box { -0.9, 0.9 } }
  rotate <20, 30, 0> translate <-3, 1.1, 0.5> pigment { rgb <1, 0.3, 0.2> } finish { phong 0.6 } }
isosurface { function { y - 0.25 * sin(x * 3) * cos(z * 2) } max_gradient 1.3 contained_by { sphere { 0, 1 } }
  translate <0, 1.1, 0> pigment { rgb <0.2, 0.8, 0.3> } }
isosurface { function { abs(x) + abs(y) + abs(z) } threshold 1.2 max_gradient 1.8 open contained_by { box { <-1, -1, -1>, <1, 0.5, 1> } }
  rotate y * 25 translate <3, 1, 0.5> pigment { rgb <0.3, 0.4, 1> } finish { specular 0.5 roughness 0.02 } }
