// checks: blob (sphere and cylinder components with strengths, one negative; a component scaled into an ellipsoid and one turned; the threshold; the obsolete component form), moved, with highlights, shadows and a glass blob's filtered shadow
#version 3.7;
global_settings { assumed_gamma 1.0 }
camera { location <0, 3.5, -8> look_at <0, 0.8, 0> right x*image_width/image_height angle 50 }
light_source { <-8, 15, -12> color rgb 1 }
light_source { <10, 8, -4> color rgb 0.4 }
plane { y, 0 pigment { checker rgb 0.8, rgb 0.3 } }
blob {
  threshold 0.5
  sphere { <-0.9, 0, 0>, 1, 2 }
  cylinder { <-1.2, 0, 0>, <1.2, 0, 0>, 0.45, 1 }
  cylinder { <0, -1, 0>, <0, 1, 0>, 0.45, 1 rotate z * 35 }
  sphere { <0.9, 0, 0>, 0.7, strength 1.5 scale <1, 1.7, 1> }
  sphere { <0.1, 0.4, -0.5>, 0.5, -1 }
  pigment { rgb <1, 0.45, 0.2> } finish { phong 0.6 }
  rotate y * 25 translate <-2.2, 1.2, 0.5>
}
blob {
  threshold 0.6
  component 1, 1, <0, 0, 0>
  component 1, 1, <0.75, 0.6, 0>
  component 1, 1, <-0.75, 0.6, 0>
  component 1, 1, <0, 1.2, 0>
  pigment { rgb <0.2, 0.8, 0.3> } finish { specular 0.5 roughness 0.02 }
  translate <0.6, 0.55, 1.5>
}
blob {
  threshold 0.4
  #for (I, 0, 5)
    sphere { <cos(I * pi / 3), 0, sin(I * pi / 3)>, 0.8, 1 }
  #end
  pigment { rgbf <0.7, 0.8, 1, 0.7> } finish { phong 0.8 }
  scale 0.75 translate <2.6, 0.45, -0.2>
}
