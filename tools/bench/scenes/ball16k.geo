// The ~16k-node ball of tools/bench/scenes/ball16k.msh (make_ball.py): radius 50 (mm: sim --scene-unit-m 0.001).
SetFactory("OpenCASCADE");
Sphere(1) = {0, 0, 0, 50};
Mesh.CharacteristicLengthMax = 3.0;
Mesh.CharacteristicLengthMin = 3.0;
