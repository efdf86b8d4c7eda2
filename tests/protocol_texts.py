"""Small protocol files the tests write out (YAML text)."""

ELBOW_R = """name: elbow_r
segments:
  upperarm_r: {side: r, sensor_axes: [x, y, z]}
  forearm_r: {side: r, sensor_axes: [z, y, -x]}
calibration:
  - {name: standing, kind: static, pose: standing, duration_s: 4, vertical_axis: {upperarm_r: y}}
  - {name: shoulder_flexion_r, kind: functional, axis: {upperarm_r: z, forearm_r: z},
     repetitions: 3, duration_s: 8}
  - {name: elbow_flexion_r, kind: functional, axis: {forearm_r: z}, repetitions: 3,
     duration_s: 8}
  - {name: pronation_r, kind: functional, axis: {forearm_r: y}, repetitions: 3, duration_s: 8}
joints:
  elbow_r: {type: elbow, proximal: upperarm_r, distal: forearm_r, side: r}
tasks:
  - {name: curls, kind: elbow_flexion, repetitions: 4, duration_s: 12}
metrics: [rom, cycles, cross_talk]
"""
