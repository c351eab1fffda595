// checks: polynomial surfaces: a torus as a quartic (rotated), a rounded cube as a polynomial of
// order 4, a cubic saddle intersected with a box (a CSG member), and their shadows
#version 3.7;
global_settings { assumed_gamma 1.0 max_trace_level 5 }
camera { location <0.3, 2.2, -5.5> look_at <0.1, 0.55, 0> right x*image_width/image_height angle 48 }
light_source { <-30, 50, -20> color rgb 1 }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.65> } finish { ambient 0.1 diffuse 0.6 } }
// (x² + y² + z² + R² - r²)² - 4R² (x² + z²), R = 0.6, r = 0.2
quartic {
  < 1,  0,  0,  0,  2,  0,  0,  2,  0, -0.8,
    0,  0,  0,  0,  0,  0,  0,  0,  0,  0,
    1,  0,  0,  2,  0, 0.64, 0,  0,  0,  0,
    1,  0, -0.8, 0,  0.1024 >
  sturm
  rotate <60, 0, 20> translate <-1.2, 0.75, 0.3>
  pigment { rgb <0.9, 0.6, 0.2> } finish { ambient 0.1 diffuse 0.8 phong 0.4 }
}
// x⁴ + y⁴ + z⁴ = 0.2
polynomial { 4, xyz(4, 0, 0): 1, xyz(0, 4, 0): 1, xyz(0, 0, 4): 1, xyz(0, 0, 0): -0.2
  rotate <0, 30, 0> translate <0.3, 0.67, -0.4>
  pigment { rgb <0.3, 0.5, 0.9> } finish { ambient 0.1 diffuse 0.8 }
}
// z = x³ - y³ (shapesq.inc's Cubic_Saddle_1, there written as a quartic), in a box
intersection {
  cubic { < 1, 0, 0, 0, 0, 0, 0, 0, 0, 0, -1, 0, 0, 0, 0, 0, 0, 0, -1, 0 > }
  box { <-0.6, -0.6, -0.6>, <0.6, 0.6, 0.6> }
  rotate <-90, 0, 0> translate <1.5, 0.61, 0.5>
  pigment { rgb <0.4, 0.8, 0.4> } finish { ambient 0.15 diffuse 0.7 }
}
