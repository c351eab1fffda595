// checks: superellipsoid (rounded box, rounded cylinder, sphere-like and a non-convex star), rotated, scaled and translated, with shadows
#version 3.7;
global_settings { assumed_gamma 1.0 adc_bailout 0 max_trace_level 5 }
camera { location <0.3, 2.4, -5.6> look_at <0.1, 0.55, 0> right x*image_width/image_height angle 50 }
light_source { <-30, 50, -20> color rgb 1 parallel point_at <0, 0, 0> }
plane { y, 0 pigment { rgb <0.7, 0.7, 0.65> } finish { ambient 0.1 diffuse 0.6 } }
superellipsoid { <0.25, 0.25> scale 0.55 rotate <0, 30, 0> translate <-1.5, 0.55, 0.4> pigment { rgb <0.9, 0.6, 0.2> } finish { ambient 0.1 diffuse 0.8 } }
superellipsoid { <1, 0.3> scale <0.45, 0.45, 0.6> rotate <90, 0, 0> translate <-0.1, 0.6, 0.9> pigment { rgb <0.3, 0.5, 0.9> } finish { ambient 0.1 diffuse 0.8 } }
superellipsoid { <0.8, 1.6> scale 0.5 rotate <20, 0, -25> translate <1.3, 0.6, 0.3> pigment { rgb <0.4, 0.8, 0.4> } finish { ambient 0.1 diffuse 0.8 } }
superellipsoid { <3, 2.5> scale 0.7 rotate <0, 20, 10> translate <0.1, 0.75, -1.0> pigment { rgb <0.85, 0.3, 0.35> } finish { ambient 0.1 diffuse 0.8 } }
