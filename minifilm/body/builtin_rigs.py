"""The hierarchies of the built-in target rigs other than 100STYLE (whose header is in
minifilm/synthetic/body.py), so that ``minifilm retarget --to bandai`` or ``--to cmu`` needs no file.

* ``bandai``: the header of Bandai Namco Research Motion Dataset 1 (CC BY-NC 4.0, Bandai Namco
  Research Inc.; Kobayashi et al. 2023): 22 joints, six channels each, centimetres, rooted at the
  floor marker ``joint_Root``.
* ``cmu``: the 31-joint CMU skeleton as in the Xia et al. 2015 clips converted by
  deep-motion-editing (CMU data: free for research and commercial use, with acknowledgement), in
  the CMU ASF length unit (``skeletons.CMU.bvh_scale`` turns it into metres).

Each is one BVH HIERARCHY; :func:`minifilm.body.target.builtin_rig` adds one frame at rest. Also here:
the Bandai foot's measured shape.
"""
import numpy as np


BANDAI_HIERARCHY = """\
HIERARCHY
ROOT joint_Root
{
 OFFSET 0 0 0
 CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
 JOINT Hips
 {
  OFFSET 0 93.9241 -3
  CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
  JOINT Spine
  {
   OFFSET 15.7357 0 0
   CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
   JOINT Chest
   {
    OFFSET 8.98455 -0.406207 0
    CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
    JOINT Neck
    {
     OFFSET 16.3773 0 0
     CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
     JOINT Head
     {
      OFFSET 6.45672 0 0
      CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
      End Site
      {
       OFFSET 0 0 0
      }
     }
    }
    JOINT Shoulder_L
    {
     OFFSET 12.9942 -0.242716 4.98039
     CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
     JOINT UpperArm_L
     {
      OFFSET 5.34809 0 0
      CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
      JOINT LowerArm_L
      {
       OFFSET 24.3286 1.87007e-05 0
       CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
       JOINT Hand_L
       {
        OFFSET 22.2916 0 0
        CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
        End Site
        {
         OFFSET 0 0 0
        }
       }
      }
     }
    }
    JOINT Shoulder_R
    {
     OFFSET 12.9945 -0.242716 -4.98039
     CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
     JOINT UpperArm_R
     {
      OFFSET -5.34813 0 0
      CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
      JOINT LowerArm_R
      {
       OFFSET -24.3289 0.000322201 0
       CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
       JOINT Hand_R
       {
        OFFSET -22.2915 -0.000108084 0
        CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
        End Site
        {
         OFFSET 0 0 0
        }
       }
      }
     }
    }
   }
  }
  JOINT UpperLeg_L
  {
   OFFSET -2.19248 -6.46944 0
   CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
   JOINT LowerLeg_L
   {
    OFFSET 39.0811 0 -1.23785e-05
    CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
    JOINT Foot_L
    {
     OFFSET 40.9854 0 -1.26872e-05
     CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
     JOINT Toes_L
     {
      OFFSET 11.7543 0 0
      CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
      End Site
      {
       OFFSET 0 0 0
      }
     }
    }
   }
  }
  JOINT UpperLeg_R
  {
   OFFSET -2.19251 6.46944 0
   CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
   JOINT LowerLeg_R
   {
    OFFSET -39.0811 -0.00228153 -0.0401928
    CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
    JOINT Foot_R
    {
     OFFSET -40.9854 0 0
     CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
     JOINT Toes_R
     {
      OFFSET -11.7543 0 0
      CHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
      End Site
      {
       OFFSET 0 0 0
      }
     }
    }
   }
  }
 }
}
"""

CMU_HIERARCHY = """\
HIERARCHY
ROOT Hips
{
 OFFSET 0.000000 0.000000 0.000000
 CHANNELS 6 Xposition Yposition Zposition Zrotation Yrotation Xrotation
 JOINT LHipJoint
 {
  OFFSET 0.000000 0.000000 0.000000
  CHANNELS 3 Zrotation Yrotation Xrotation
  JOINT LeftUpLeg
  {
   OFFSET 1.363060 -1.794630 0.839290
   CHANNELS 3 Zrotation Yrotation Xrotation
   JOINT LeftLeg
   {
    OFFSET 2.448110 -6.726130 0.000000
    CHANNELS 3 Zrotation Yrotation Xrotation
    JOINT LeftFoot
    {
     OFFSET 2.562200 -7.039590 0.000000
     CHANNELS 3 Zrotation Yrotation Xrotation
     JOINT LeftToeBase
     {
      OFFSET 0.157640 -0.433110 2.322550
      CHANNELS 3 Zrotation Yrotation Xrotation
      End Site
      {
       OFFSET 0.000000 0.000000 0.000000
      }
     }
    }
   }
  }
 }
 JOINT RHipJoint
 {
  OFFSET 0.000000 0.000000 0.000000
  CHANNELS 3 Zrotation Yrotation Xrotation
  JOINT RightUpLeg
  {
   OFFSET -1.305520 -1.794630 0.839290
   CHANNELS 3 Zrotation Yrotation Xrotation
   JOINT RightLeg
   {
    OFFSET -2.542530 -6.985550 0.000000
    CHANNELS 3 Zrotation Yrotation Xrotation
    JOINT RightFoot
    {
     OFFSET -2.568260 -7.056230 0.000000
     CHANNELS 3 Zrotation Yrotation Xrotation
     JOINT RightToeBase
     {
      OFFSET -0.164730 -0.452590 2.363150
      CHANNELS 3 Zrotation Yrotation Xrotation
      End Site
      {
       OFFSET 0.000000 0.000000 0.000000
      }
     }
    }
   }
  }
 }
 JOINT LowerBack
 {
  OFFSET 0.000000 0.000000 0.000000
  CHANNELS 3 Zrotation Yrotation Xrotation
  JOINT Spine
  {
   OFFSET 0.028270 2.035590 -0.193380
   CHANNELS 3 Zrotation Yrotation Xrotation
   JOINT Spine1
   {
    OFFSET 0.056720 2.048850 -0.042750
    CHANNELS 3 Zrotation Yrotation Xrotation
    JOINT Neck
    {
     OFFSET 0.000000 0.000000 0.000000
     CHANNELS 3 Zrotation Yrotation Xrotation
     JOINT Neck1
     {
      OFFSET -0.054170 1.746240 0.172020
      CHANNELS 3 Zrotation Yrotation Xrotation
      JOINT Head
      {
       OFFSET 0.104070 1.761360 -0.123970
       CHANNELS 3 Zrotation Yrotation Xrotation
       End Site
       {
        OFFSET 0.000000 0.000000 0.000000
       }
      }
     }
    }
    JOINT LeftShoulder
    {
     OFFSET 0.000000 0.000000 0.000000
     CHANNELS 3 Zrotation Yrotation Xrotation
     JOINT LeftArm
     {
      OFFSET 3.362410 1.200890 -0.311210
      CHANNELS 3 Zrotation Yrotation Xrotation
      JOINT LeftForeArm
      {
       OFFSET 4.983000 -0.000000 -0.000000
       CHANNELS 3 Zrotation Yrotation Xrotation
       JOINT LeftHand
       {
        OFFSET 3.483560 -0.000000 -0.000000
        CHANNELS 3 Zrotation Yrotation Xrotation
        JOINT LeftFingerBase
        {
         OFFSET 0.000000 0.000000 0.000000
         CHANNELS 3 Zrotation Yrotation Xrotation
         JOINT LeftHandIndex1
         {
          OFFSET 0.715260 -0.000000 -0.000000
          CHANNELS 3 Zrotation Yrotation Xrotation
          End Site
          {
           OFFSET 0.000000 0.000000 0.000000
          }
         }
        }
        JOINT LThumb
        {
         OFFSET 0.000000 0.000000 0.000000
         CHANNELS 3 Zrotation Yrotation Xrotation
         End Site
         {
          OFFSET 0.000000 0.000000 0.000000
         }
        }
       }
      }
     }
    }
    JOINT RightShoulder
    {
     OFFSET 0.000000 0.000000 0.000000
     CHANNELS 3 Zrotation Yrotation Xrotation
     JOINT RightArm
     {
      OFFSET -3.136600 1.374050 -0.404650
      CHANNELS 3 Zrotation Yrotation Xrotation
      JOINT RightForeArm
      {
       OFFSET -5.241900 -0.000000 -0.000000
       CHANNELS 3 Zrotation Yrotation Xrotation
       JOINT RightHand
       {
        OFFSET -3.444170 -0.000000 -0.000000
        CHANNELS 3 Zrotation Yrotation Xrotation
        JOINT RightFingerBase
        {
         OFFSET 0.000000 0.000000 0.000000
         CHANNELS 3 Zrotation Yrotation Xrotation
         JOINT RightHandIndex1
         {
          OFFSET -0.622530 -0.000000 -0.000000
          CHANNELS 3 Zrotation Yrotation Xrotation
          End Site
          {
           OFFSET 0.000000 0.000000 0.000000
          }
         }
        }
        JOINT RThumb
        {
         OFFSET 0.000000 0.000000 0.000000
         CHANNELS 3 Zrotation Yrotation Xrotation
         End Site
         {
          OFFSET 0.000000 0.000000 0.000000
         }
        }
       }
      }
     }
    }
   }
  }
 }
}
"""


#: The Bandai rig's zero pose is no standing pose (every bone along x), so its flat foot is
#: measured: the 10th percentile of the ankle -> toe pitch over the toe's contact frames is 39.6
#: degrees in every shared Bandai walk (proportions.motion_foot_pitch); its toe tip has no
#: length, so no toe bend is aimed on it.
BANDAI_FOOT_SHAPE = (float(np.radians(39.6)), 0.0)
