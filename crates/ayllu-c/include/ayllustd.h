/* ayllustd.h — the standard behaviors of the paper's Fig. 2 (`MakeSafeVelBeh`,
 * `MakeWanderBeh`, the observer) and the robot's body in place of `ayInitPioControl` (the
 * simulator's, or a ROS 2 robot's), from the runtime's standard library (ayllu::stdlib). They
 * work on the default node (ayInitIPComms). docs/c-api.md describes each. */
#ifndef AYLLUSTD_H
#define AYLLUSTD_H

#include "ayllu.h"

/* The robot body of a world served by `ayllu sim serve`, for `Targets` targets: VISION
 * (Target<n>Angle: bearing, rad, right-positive; Target<n>Bottom: apparent height, larger is
 * closer), SONAR (Ranges) and BASE (Rotate: rad/s, left-positive; Translate: m/s) on this
 * node, whose id must be the robot's number (1 to 999). Call after ayInitIPComms. */
#define ayInitSimBody(Targets) ((void)ay_check_(ay_sim_body(ayNODE, (Targets)), "ayInitSimBody"))

/* The ROS 2 body (docs/ros2.md): the behaviors the mapping file `File` names (VISION, SONAR,
 * BASE for Fig. 2) on this node, their ports ROS 2 topics (a LaserScan on /robot2/scan into
 * SONAR.Ranges, BASE.Rotate and BASE.Translate out as a Twist on /robot2/cmd_vel, ...); `{id}`
 * in the file stands for the node's id. In place of ayInitSimBody, so Fig. 2 moves from the
 * simulator to a robot by changing that one line. Call after ayInitIPComms. Needs libayllu
 * built with the ROS 2 body (`make ros2`); otherwise, and for a wrong mapping file, it fails
 * with the reason (the file, the field and the fix) in ay_last_error(). */
#define ayInitRos2Body(File) ((void)ay_check_(ay_ros2_body(ayNODE, (File)), "ayInitRos2Body"))

/* Safe velocity from sonar (`SafeVelocity`, 10 Hz), wired SONAR.Ranges -> Name.Ranges and
 * Name.Translate -> BASE.Translate when the body exists. */
#define MakeSafeVelBeh(Name) ((void)ay_check_(ay_std_safe_velocity(ayNODE, #Name), "MakeSafeVelBeh(" #Name ")"))

/* A random wander (`RandomWander`, 10 Hz) seeded with `Seed` (mixed with the node id),
 * wired Name.Rotate -> BASE.Rotate when the body exists; MakeWanderBeh uses seed 1. The first
 * wander made on a node fixes the seed of its class. */
#define MakeWanderBehSeeded(Name, Seed) \
    ((void)ay_check_(ay_std_wander(ayNODE, #Name, (uint64_t)(Seed)), "MakeWanderBeh(" #Name ")"))
#define MakeWanderBeh(Name) MakeWanderBehSeeded(Name, 1)

/* The standard observer layer of Fig. 2 in one call (the C example writes it with macros
 * instead): OBS<Num> of class `Observer` fed from VISION.Target<Num>Angle/Bottom, overriding
 * Next.Rotate for 0.2 s, a BLE peer of `Group` claiming `Rate` times a second. */
#define MakeStdObserver(Num, Next, Group, Rate)                                              \
    ((void)ay_check_(ay_std_observer(ayNODE, (Num), #Next, (Group).name, (Rate)),           \
                     "MakeStdObserver(" #Num ", " #Next ")"))

#endif /* AYLLUSTD_H */
