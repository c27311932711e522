// Headless check of the generated lcm-spy jar: every lifmcr type loads, and
// the depth messages of an lcm-logger log decode with the Java classes.
// Usage: java -cp lcm.jar:lifmcr_lcm_types.jar:DIR JarCheck LOG
import lcm.logging.Log;

public class JarCheck {
  public static void main(String[] args) throws Exception {
    String[] types = {"preview_image_t", "depth_image_t", "camera_extrinsics_t", "camera_pose_t",
                      "vicon_object_t", "vicon_frame_t", "stage_stats_t", "drop_count_t",
                      "pipeline_stats_t"};
    for (String t : types) Class.forName("lifmcr_lcm." + t);
    Log log = new Log(args[0], "r");
    int depth = 0, preview = 0;
    while (true) {
      Log.Event e;
      try {
        e = log.readNext();
      } catch (java.io.EOFException end) {
        break;
      }
      if (e.channel.endsWith("_DEPTH")) {
        lifmcr_lcm.depth_image_t m = new lifmcr_lcm.depth_image_t(e.data);
        if (m.width <= 0 || m.size != m.data.length) throw new RuntimeException("bad depth");
        ++depth;
      } else if (e.channel.endsWith("_PREVIEW")) {
        lifmcr_lcm.preview_image_t m = new lifmcr_lcm.preview_image_t(e.data);
        if (m.size != m.data.length) throw new RuntimeException("bad preview");
        ++preview;
      }
    }
    System.out.println("types " + types.length + " depth " + depth + " preview " + preview);
  }
}
