/* motion_clips.c: procedural motion clips for garment simulation: walk, run,
 * jump, bend, raise_arms, squat, twist, dance, stairs, dodge, reach, lean and
 * stretch.
 *
 * Each clip is a function of time built from a handful of joint angles
 * (sinusoids for cycles, smooth bumps for phases such as a jump's crouch,
 * flight and landing), composed per joint as rotations about anatomical
 * axes of the rest pose: flexion about X, abduction and side bending about
 * Z, twist about Y. Every angle and displacement is multiplied by an
 * ease-in ramp (smootherstep, zero value, velocity and acceleration at
 * t = 0) so frame 0 is exactly the rest pose and the velocity is
 * continuous; locomotion advances by the speed times the ramp's integral.
 * The rest pose is the mannequin's A-pose, so arm angles are relative to
 * arms 40 to 45 degrees down: raising them overhead is about 2.1 rad of
 * abduction (collar and shoulder together).
 *
 * Amplitudes are plausible for an adult, not captured: knees bend at most
 * 1.9 rad (squat), shoulders lift at most 2.2 rad with the collar, the spine
 * bends at most 0.85 rad over its three joints. Cycle lengths and speeds are
 * written at each clip (walking 1.1 s per cycle at 1.3 m/s, running 0.72 s
 * at 3.6 m/s).
 *
 * Leaves out foot contact: feet may slide a little, which garments do not
 * notice. References: Winter, "Biomechanics and Motor Control of Human
 * Movement" (gait joint-angle curves, used for shapes and ranges);
 * Perlin's smootherstep 6x^5 - 15x^4 + 10x^3.
 */
#include "body/motion_internal.h"

#include <string.h>

#define CLIP_COOKIE 0x636c6970u
static const double TAU = 2.0 * M_PI;
static const double INV_SQRT2 = 0.70710678118654752;

/* One frame being built: joint rotations as quaternions, composed in the
 * order the clip adds them (each about the joint's current local axes). */
typedef struct clip_frame {
    double ph;       /* tempo-scaled time, s */
    double ramp;     /* ease-in weight times the amplitude, 0..amp */
    double distance; /* amp * speed * integral of the ramp, s: times m/s gives m */
    double q[CR_NJOINTS][4];
    double trans[3]; /* m: offsets carry the ramp, travel comes from `distance` */
} clip_frame;

/* Rotate joint j by `angle` (before the ramp) about the unit axis a. */
static void turn(clip_frame *c, int j, double ax, double ay, double az, double angle) {
    double r[4];
    q_axis(ax, ay, az, c->ramp * angle, r);
    q_mul(c->q[j], r, c->q[j]);
}

/* Anatomical shorthands; positive angles are the named motion. side: 0 left, 1 right. */
static void hip_flex(clip_frame *c, int side, double a) {
    turn(c, CR_JOINT_LEFT_HIP + side, 1, 0, 0, -a); /* thigh forward (+Z) */
}
static void hip_abduct(clip_frame *c, int side, double a) {
    turn(c, CR_JOINT_LEFT_HIP + side, 0, 0, 1, side ? -a : a); /* leg outward */
}
static void hip_twist(clip_frame *c, int side, double a) {
    turn(c, CR_JOINT_LEFT_HIP + side, 0, 1, 0, a);
}
static void knee_flex(clip_frame *c, int side, double a) {
    turn(c, CR_JOINT_LEFT_KNEE + side, 1, 0, 0, a); /* shin backward */
}
static void ankle_flex(clip_frame *c, int side, double a) {
    turn(c, CR_JOINT_LEFT_ANKLE + side, 1, 0, 0, a); /* toes down (plantarflexion) */
}
static void bend(clip_frame *c, int j, double a) {
    turn(c, j, 1, 0, 0, a); /* torso or head forward */
}
static void lean(clip_frame *c, int j, double a) {
    turn(c, j, 0, 0, 1, -a); /* toward the body's left (+X) */
}
static void twist(clip_frame *c, int j, double a) {
    turn(c, j, 0, 1, 0, a); /* turn left: +Z toward +X */
}
static void arm_raise(clip_frame *c, int side, double a) {
    turn(c, CR_JOINT_LEFT_SHOULDER + side, 0, 0, 1, side ? -a : a); /* abduction, up and out */
}
static void arm_swing(clip_frame *c, int side, double a) {
    turn(c, CR_JOINT_LEFT_SHOULDER + side, 1, 0, 0, -a); /* forward flexion */
}
static void shrug(clip_frame *c, int side, double a) {
    turn(c, CR_JOINT_LEFT_COLLAR + side, 0, 0, 1, side ? -a : a);
}
/* About the horizontal axis across the A-pose arm, so the forearm comes forward. */
static void elbow_flex(clip_frame *c, int side, double a) {
    turn(c, CR_JOINT_LEFT_ELBOW + side, -INV_SQRT2, side ? INV_SQRT2 : -INV_SQRT2, 0, a);
}

/* sin^2 bump on [a, b] of a cycle phase u in [0, 1), 0 elsewhere: C1 at both ends. */
static double bump(double u, double a, double b) {
    if (u <= a || u >= b) return 0;
    double s = sin(M_PI * (u - a) / (b - a));
    return s * s;
}

/* 0 -> 1 -> 0 over a cycle, smooth everywhere. */
static double hump(double u) {
    return 0.5 * (1 - cos(TAU * u));
}

static double cycle(double ph, double period) {
    double u = ph / period;
    return u - floor(u);
}

/* Knee flexion of a gait: peaks in early swing, small at heel strike. */
static double gait_knee(double phase, double base, double peak, double lead) {
    double k = 0.5 * (1 + cos(phase + lead));
    return base + peak * k * k;
}

/* Relaxed arms for locomotion: in from the A-pose, swinging against the legs. */
static void gait_arms(clip_frame *c, double phi, double in, double swing, double elbow) {
    for (int s = 0; s < 2; s++) {
        double ps = phi + (s ? 0 : M_PI); /* the left arm swings with the right leg */
        arm_raise(c, s, -in);
        arm_swing(c, s, swing * sin(ps));
        elbow_flex(c, s, elbow + 0.1 * sin(ps));
    }
}

static void clip_walk(clip_frame *c) {
    const double period = 1.1, speed = 1.27; /* s per cycle (two steps), m/s */
    double phi = TAU * c->ph / period;
    for (int s = 0; s < 2; s++) {
        double ps = phi + (s ? M_PI : 0);
        hip_flex(c, s, 0.05 + 0.38 * sin(ps));
        knee_flex(c, s, gait_knee(ps, 0.08, 0.62, 0.3));
        ankle_flex(c, s, -0.15 * sin(ps));
    }
    twist(c, CR_JOINT_PELVIS, -0.08 * sin(phi));
    twist(c, CR_JOINT_SPINE3, 0.1 * sin(phi));
    lean(c, CR_JOINT_PELVIS, 0.03 * cos(phi));
    gait_arms(c, phi, 0.35, 0.3, 0.25);
    c->trans[0] = c->ramp * 0.015 * sin(phi);
    c->trans[1] = c->ramp * -0.01 * (1 - cos(2 * phi));
    c->trans[2] = speed * c->distance;
}

static void clip_run(clip_frame *c) {
    const double period = 0.72, speed = 3.6; /* s per cycle, m/s */
    double phi = TAU * c->ph / period;
    for (int s = 0; s < 2; s++) {
        double ps = phi + (s ? M_PI : 0);
        hip_flex(c, s, 0.2 + 0.55 * sin(ps));
        knee_flex(c, s, gait_knee(ps, 0.35, 1.2, 0.4));
        ankle_flex(c, s, -0.25 * sin(ps));
    }
    bend(c, CR_JOINT_SPINE1, 0.12);
    bend(c, CR_JOINT_SPINE2, 0.05);
    twist(c, CR_JOINT_PELVIS, -0.12 * sin(phi));
    twist(c, CR_JOINT_SPINE3, 0.15 * sin(phi));
    gait_arms(c, phi, 0.45, 0.55, 1.35);
    c->trans[1] = c->ramp * -0.025 * (1 - cos(2 * phi));
    c->trans[2] = speed * c->distance;
}

/* Repeated standing jumps: crouch, take off, fly 0.25 m up and come down no
 * faster than gravity allows (the flight bump spans 0.72 s, so its curvature
 * at the top is 9.5 m/s^2), land and absorb. */
static void clip_jump(clip_frame *c) {
    double u = cycle(c->ph, 1.6);
    double crouch = bump(u, 0.0, 0.42), fly = bump(u, 0.30, 0.75), land = bump(u, 0.66, 0.98);
    for (int s = 0; s < 2; s++) {
        hip_flex(c, s, 1.0 * crouch + 0.6 * land);
        knee_flex(c, s, 1.3 * crouch + 0.9 * land);
        ankle_flex(c, s, -0.35 * (crouch + 0.7 * land) + 0.35 * fly);
        arm_swing(c, s, -0.6 * bump(u, 0.0, 0.33) + 1.9 * bump(u, 0.22, 0.75));
        elbow_flex(c, s, 0.3 + 0.3 * crouch);
    }
    bend(c, CR_JOINT_SPINE1, 0.3 * crouch + 0.15 * land);
    bend(c, CR_JOINT_SPINE2, 0.1 * crouch);
    c->trans[1] = c->ramp * (-0.28 * (crouch + 0.7 * land) + 0.25 * fly);
}

/* Bending forward at the waist with straight legs, and back up. */
static void clip_bend(clip_frame *c) {
    double b = hump(cycle(c->ph, 4.0));
    bend(c, CR_JOINT_PELVIS, 0.55 * b);
    for (int s = 0; s < 2; s++) {
        hip_flex(c, s, 0.55 * b); /* the legs stay vertical under the tilting pelvis */
        knee_flex(c, s, 0.1 * b);
        arm_swing(c, s, 1.2 * b); /* arms keep hanging toward the floor */
        arm_raise(c, s, -0.2 * b);
    }
    bend(c, CR_JOINT_SPINE1, 0.35 * b);
    bend(c, CR_JOINT_SPINE2, 0.3 * b);
    bend(c, CR_JOINT_SPINE3, 0.2 * b);
    bend(c, CR_JOINT_NECK, -0.3 * b);
    c->trans[1] = c->ramp * -0.03 * b;
    c->trans[2] = c->ramp * -0.08 * b;
}

static void clip_raise_arms(clip_frame *c) {
    double b = hump(cycle(c->ph, 4.0));
    for (int s = 0; s < 2; s++) {
        shrug(c, s, 0.3 * b);
        arm_raise(c, s, 1.85 * b);
        arm_swing(c, s, 0.15 * b);
        elbow_flex(c, s, 0.15 * b);
    }
    bend(c, CR_JOINT_SPINE3, -0.08 * b);
}

static void clip_squat(clip_frame *c) {
    double b = hump(cycle(c->ph, 3.5));
    for (int s = 0; s < 2; s++) {
        hip_flex(c, s, 1.45 * b);
        knee_flex(c, s, 1.9 * b);
        ankle_flex(c, s, -0.45 * b); /* the shin leans 0.45 rad forward, the foot stays flat */
        arm_swing(c, s, 1.3 * b);    /* arms forward for balance */
        arm_raise(c, s, -0.3 * b);
    }
    bend(c, CR_JOINT_SPINE1, 0.35 * b);
    bend(c, CR_JOINT_SPINE2, 0.15 * b);
    /* Legs of 0.45 m + 0.45 m at these angles put the pelvis 0.44 m lower, 0.25 m back. */
    c->trans[1] = c->ramp * -0.44 * b;
    c->trans[2] = c->ramp * -0.25 * b;
}

/* Turning the torso left and right over planted feet. */
static void clip_twist(clip_frame *c) {
    double s = sin(TAU * c->ph / 3.0);
    twist(c, CR_JOINT_PELVIS, 0.15 * s);
    for (int side = 0; side < 2; side++) {
        hip_twist(c, side, -0.15 * s);
        arm_raise(c, side, -0.1);
        arm_swing(c, side, (side ? 0.25 : -0.25) * s);
        elbow_flex(c, side, 0.3);
    }
    twist(c, CR_JOINT_SPINE1, 0.2 * s);
    twist(c, CR_JOINT_SPINE2, 0.2 * s);
    twist(c, CR_JOINT_SPINE3, 0.2 * s);
    twist(c, CR_JOINT_NECK, 0.1 * s);
    twist(c, CR_JOINT_HEAD, 0.05 * s);
}

/* Swaying side to side to a 2 s beat, arms swinging, a slow turn of the chest. */
static void clip_dance(clip_frame *c) {
    double phi = TAU * c->ph / 2.0, s = sin(phi);
    lean(c, CR_JOINT_PELVIS, 0.1 * s);
    lean(c, CR_JOINT_SPINE1, -0.12 * s);
    lean(c, CR_JOINT_SPINE3, -0.06 * s);
    twist(c, CR_JOINT_SPINE2, 0.15 * sin(0.5 * phi));
    for (int side = 0; side < 2; side++) {
        double sign = side ? -1 : 1;
        knee_flex(c, side, 0.15 * (1 - sign * s));
        hip_flex(c, side, 0.08 * (1 - sign * s));
        hip_abduct(c, side, -0.1 * sign * s); /* feet stay under the swaying pelvis */
        arm_raise(c, side, 0.5 + 0.45 * sign * s);
        arm_swing(c, side, 0.4 * sign * cos(phi));
        elbow_flex(c, side, 0.7 + 0.4 * sin(2 * phi));
    }
    bend(c, CR_JOINT_HEAD, 0.1 * sin(2 * phi));
    c->trans[0] = c->ramp * 0.07 * s;
    c->trans[1] = c->ramp * -0.015 * (1 - cos(2 * phi));
}

/* Climbing stairs of 0.17 m rise and 0.28 m tread, one step per half cycle. */
static void clip_stairs(clip_frame *c) {
    const double period = 1.4, rise = 0.17, tread = 0.28;
    double phi = TAU * c->ph / period;
    for (int s = 0; s < 2; s++) {
        double ps = phi + (s ? M_PI : 0);
        hip_flex(c, s, 0.45 + 0.45 * sin(ps));
        knee_flex(c, s, gait_knee(ps, 0.15, 1.05, 0.3));
        ankle_flex(c, s, -0.15 * sin(ps));
    }
    bend(c, CR_JOINT_SPINE1, 0.12);
    twist(c, CR_JOINT_PELVIS, -0.06 * sin(phi));
    gait_arms(c, phi, 0.35, 0.2, 0.3);
    c->trans[1] = 2 * rise / period * c->distance;
    c->trans[2] = 2 * tread / period * c->distance;
}

/* Dodging left and right: side-steps with a lean and a duck at each side. */
static void clip_dodge(clip_frame *c) {
    double phi = TAU * c->ph / 2.4, s = sin(phi), duck = 0.5 * (1 - cos(2 * phi));
    lean(c, CR_JOINT_SPINE1, 0.25 * s);
    lean(c, CR_JOINT_SPINE2, 0.15 * s);
    for (int side = 0; side < 2; side++) {
        hip_abduct(c, side, (side ? 0.2 : -0.2) * s); /* the feet trail the pelvis */
        hip_flex(c, side, 0.4 * duck);
        knee_flex(c, side, 0.5 * duck);
        arm_swing(c, side, 0.6 + 0.2 * duck); /* guard up */
        arm_raise(c, side, -0.2);
        elbow_flex(c, side, 1.3);
    }
    bend(c, CR_JOINT_SPINE2, 0.15 * duck);
    c->trans[0] = c->ramp * 0.35 * s;
    c->trans[1] = c->ramp * -0.15 * duck;
}

/* Clips whose every repetition is aimed elsewhere: repetition n of a cycle
 * of `period` s uses entry n % count of a table, and the entries change only
 * where the repetition's bump is zero with zero slope, so the clip stays C1. */
static int repetition(double ph, double period, double *u) {
    double k = floor(ph / period);
    *u = ph / period - k;
    return (int)k;
}

/* One arm at a time reaching out and back, 1 s a reach, left and right in
 * turn, each reach aimed elsewhere: overhead out to the side, straight up,
 * forward and up, up and forward, forward at shoulder height (the table has
 * five entries, so over ten reaches each arm goes everywhere). The collar
 * lifts on high reaches, the chest leans a little away from the reaching
 * arm, the other arm swings a little. Arm directions of the entries (left
 * arm, unit vector, +Y up, +Z forward): (0.09, 0.98, 0.17), (-0.04, 1.00,
 * 0.04), (0.57, 0.42, 0.71), (0.27, 0.70, 0.66), (0.75, -0.14, 0.65).
 * Covers raise_arms' range of shoulder poses one arm at a time, faster and
 * in other directions; it is not that motion. */
static void clip_reach(clip_frame *c) {
    static const struct {
        double raise, swing, elbow, shrug, lean;
    } to[5] = {
        {1.95, 0.25, 0.15, 0.30, 0.10}, /* overhead, out to the side */
        {2.05, 0.05, 0.10, 0.35, 0.12}, /* straight up */
        {0.45, 1.60, 0.10, 0.15, 0.00}, /* forward and up */
        {1.30, 1.20, 0.30, 0.25, 0.05}, /* up and forward */
        {0.15, 1.15, 0.40, 0.05, 0.00}, /* forward, shoulder height */
    };
    double u;
    const int n = repetition(c->ph, 1.0, &u), side = n % 2, k = n % 5;
    const double b = bump(u, 0.0, 1.0);
    shrug(c, side, to[k].shrug * b);
    arm_raise(c, side, to[k].raise * b);
    arm_swing(c, side, to[k].swing * b);
    elbow_flex(c, side, to[k].elbow * b);
    arm_swing(c, 1 - side, 0.2 * b);
    elbow_flex(c, 1 - side, 0.2 * b);
    lean(c, CR_JOINT_SPINE2, (side ? 1 : -1) * to[k].lean * b); /* away from the arm */
    bend(c, CR_JOINT_SPINE3, -0.05 * b * (to[k].raise > 1.0));
}

/* Leaning the torso, 1.2 s a lean, to a different depth or side each time:
 * forward by 1.25, 0.65 and 0.95 rad in all over the pelvis and the spine
 * (the hips flex so the legs stay upright, the hips go back), and to the
 * left and the right by 0.40 and 0.45 rad in the spine, the arms swinging
 * forward and back against each other throughout. Covers bend's range of
 * torso poses at other depths and with moving arms; it is not that motion. */
static void clip_lean(clip_frame *c) {
    static const struct {
        double fwd, side, swing, turn;
    } to[5] = {
        {1.25, 0.00, 0.45, 0.00},  /* deep, forward */
        {0.00, 0.40, 0.30, 0.00},  /* to the left */
        {0.65, 0.00, 0.60, 0.15},  /* halfway forward, turning a little */
        {0.00, -0.45, 0.30, 0.00}, /* to the right */
        {0.95, 0.15, 0.50, -0.10}, /* forward and a little left */
    };
    double u;
    const int k = repetition(c->ph, 1.2, &u) % 5;
    const double b = bump(u, 0.0, 1.0), f = to[k].fwd * b, sd = to[k].side * b;
    bend(c, CR_JOINT_PELVIS, 0.4 * f);
    for (int s = 0; s < 2; s++) {
        hip_flex(c, s, 0.4 * f); /* the legs stay vertical under the tilting pelvis */
        knee_flex(c, s, 0.08 * f);
        /* the arms hang toward the floor as the chest tips, and swing */
        arm_swing(c, s, 0.8 * f + (s ? -1 : 1) * to[k].swing * b * sin(2 * TAU * u));
        elbow_flex(c, s, 0.2 * b);
    }
    bend(c, CR_JOINT_SPINE1, 0.25 * f);
    bend(c, CR_JOINT_SPINE2, 0.2 * f);
    bend(c, CR_JOINT_SPINE3, 0.15 * f);
    bend(c, CR_JOINT_NECK, -0.2 * f);
    lean(c, CR_JOINT_SPINE1, 0.4 * sd);
    lean(c, CR_JOINT_SPINE2, 0.35 * sd);
    lean(c, CR_JOINT_SPINE3, 0.25 * sd);
    twist(c, CR_JOINT_SPINE2, to[k].turn * b);
    c->trans[1] = c->ramp * -0.025 * f;
    c->trans[2] = c->ramp * -0.06 * f;
}

/* Stretching with both arms up, 2.4 s a stretch: the arms rise through the
 * front to overhead at unequal heights while the chest bends to one side and
 * arches back, then come down; the side and the heights change each time
 * (three variants). Covers raise_arms' two-arms-up poses, reached through
 * the front and with a side bend; it is not that motion. */
static void clip_stretch(clip_frame *c) {
    static const struct {
        double raise[2], swing[2], side, arch;
    } to[3] = {
        {{0.90, 1.20}, {2.00, 1.50}, 0.35, 0.10},  /* bending left, the left arm higher */
        {{1.30, 0.90}, {1.30, 2.00}, -0.35, 0.10}, /* bending right, the right arm higher */
        {{0.60, 0.60}, {1.70, 1.70}, 0.00, 0.20},  /* both forward and up, arching back */
    };
    double u;
    const int k = repetition(c->ph, 2.4, &u) % 3;
    const double a = bump(u, 0.0, 1.0), sd = to[k].side * bump(u, 0.25, 0.8);
    for (int s = 0; s < 2; s++) {
        shrug(c, s, 0.3 * a);
        arm_raise(c, s, to[k].raise[s] * a);
        arm_swing(c, s, to[k].swing[s] * a);
        elbow_flex(c, s, 0.25 * a);
    }
    lean(c, CR_JOINT_SPINE1, 0.35 * sd);
    lean(c, CR_JOINT_SPINE2, 0.35 * sd);
    lean(c, CR_JOINT_SPINE3, 0.3 * sd);
    bend(c, CR_JOINT_SPINE2, -0.5 * to[k].arch * a);
    bend(c, CR_JOINT_SPINE3, -0.5 * to[k].arch * a);
}

typedef struct clip_entry {
    const char *name, *summary;
    void (*fn)(clip_frame *c);
} clip_entry;

static const clip_entry clips[] = {
    {"walk", "walking forward (+Z), 1.1 s per cycle, 1.3 m/s", clip_walk},
    {"run", "running forward (+Z), 0.72 s per cycle, 3.6 m/s", clip_run},
    {"jump", "standing jumps 0.25 m high, one every 1.6 s", clip_jump},
    {"bend", "bending forward at the waist and back up, 4 s", clip_bend},
    {"raise_arms", "raising both arms overhead and lowering them, 4 s", clip_raise_arms},
    {"squat", "squatting 0.44 m down and back up, 3.5 s", clip_squat},
    {"twist", "turning the torso left and right over planted feet, 3 s", clip_twist},
    {"dance", "swaying side to side with swinging arms, 2 s beat", clip_dance},
    {"stairs", "climbing stairs (0.17 m rise, 0.28 m tread), 1.4 s per two steps", clip_stairs},
    {"dodge", "side-stepping left and right with a lean and a duck, 2.4 s", clip_dodge},
    {"reach", "one arm at a time reaching up, overhead or forward, 1 s a reach", clip_reach},
    {"lean", "leaning the torso forward to varied depths and to the sides, 1.2 s a lean",
     clip_lean},
    {"stretch", "both arms up through the front with a side bend, 2.4 s a stretch", clip_stretch},
};
enum { NCLIPS = sizeof clips / sizeof clips[0] };

static const char *const clip_names[NCLIPS + 1] = {
    "walk",  "run",    "jump",  "bend",  "raise_arms", "squat",   "twist",
    "dance", "stairs", "dodge", "reach", "lean",       "stretch", NULL};

const char *const *cr_motion_clip_names(int *count) {
    if (count) *count = NCLIPS;
    return clip_names;
}

static const clip_entry *find_clip(const char *name) {
    for (int i = 0; i < NCLIPS; i++)
        if (strcmp(clips[i].name, name) == 0) return &clips[i];
    return NULL;
}

const char *cr_motion_clip_summary(const char *name) {
    const clip_entry *c = find_clip(name);
    return c ? c->summary : NULL;
}

cr_motion_clip_def cr_motion_clip_default_def(void) {
    cr_motion_clip_def d;
    memset(&d, 0, sizeof d);
    d.name = "walk";
    d.nframes = 120;
    d.fps = 30.0f;
    d.speed = 1.0f;
    d.amplitude = 1.0f;
    d.ease_in = 0.5f;
    d.cookie = CLIP_COOKIE;
    return d;
}

/* Smootherstep ramp r(t) over [0, T] and its integral, s. */
static void ease(double t, double T, double *r, double *integral) {
    if (t >= T) {
        *r = 1;
        *integral = 0.5 * T + (t - T);
        return;
    }
    double x = t / T;
    *r = x * x * x * (10 + x * (-15 + 6 * x));
    *integral = T * x * x * x * x * (2.5 + x * (-3 + x));
}

cr_status cr_motion_clip_make(const cr_motion_clip_def *def, cr_motion **out, cr_error *err) {
    *out = NULL;
    CR_ASSERT(def && def->cookie == CLIP_COOKIE);
    const clip_entry *clip = def->name ? find_clip(def->name) : NULL;
    if (!clip) {
        char list[200];
        int n = 0;
        for (int i = 0; i < NCLIPS; i++)
            n += snprintf(list + n, sizeof list - (size_t)n, "%s%s", i ? ", " : "", clips[i].name);
        return CR_FAIL(err, CR_ERR_INVALID, "unknown clip '%s' (clips: %s)",
                       def->name ? def->name : "(null)", list);
    }
    if (!(def->speed >= 0.25f && def->speed <= 4.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "clip speed %g, expected [0.25, 4]",
                       (double)def->speed);
    if (!(def->amplitude >= 0.0f && def->amplitude <= 1.5f))
        return CR_FAIL(err, CR_ERR_INVALID, "clip amplitude %g, expected [0, 1.5]",
                       (double)def->amplitude);
    if (!(def->ease_in >= 0.05f && def->ease_in <= 5.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "clip ease_in %g s, expected [0.05, 5]",
                       (double)def->ease_in);
    if (!(def->fps > 0.0f && def->fps <= 1000.0f))
        return CR_FAIL(err, CR_ERR_INVALID, "clip fps %g, expected (0, 1000]", (double)def->fps);
    cr_motion *m = NULL;
    CR_TRY(cr_motion_create(def->nframes, def->fps, &m, err));
    for (int32_t f = 0; f < def->nframes; f++) {
        clip_frame c;
        memset(&c, 0, sizeof c);
        double t = f / (double)def->fps, r, integral;
        ease(t, def->ease_in, &r, &integral);
        c.ph = def->speed * t;
        c.ramp = def->amplitude * r;
        c.distance = def->amplitude * def->speed * integral;
        for (int j = 0; j < CR_NJOINTS; j++)
            q_identity(c.q[j]);
        clip->fn(&c);
        for (int j = 0; j < CR_NJOINTS; j++)
            q_to_aa(c.q[j], m->poses + ((size_t)f * CR_NJOINTS + (size_t)j) * 3);
        for (int k = 0; k < 3; k++)
            m->trans[(size_t)f * 3 + (size_t)k] = (float)c.trans[k];
    }
    *out = m;
    return CR_OK;
}

cr_status cr_motion_clip(const char *name, int32_t nframes, float fps, cr_motion **out,
                         cr_error *err) {
    cr_motion_clip_def def = cr_motion_clip_default_def();
    def.name = name;
    def.nframes = nframes;
    def.fps = fps;
    return cr_motion_clip_make(&def, out, err);
}
