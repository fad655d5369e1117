/*
 * The first cluster program (docs/CLUSTER.md, "Write your first cluster
 * program"): the FC opens the cluster and sends it a task; core 0 forks on
 * every core, and each core prints its ids under the team's mutex.
 */
#include <pmsis.h>
#include <stdio.h>

static void hello(void *arg)
{
    (void)arg;
    pi_cl_team_critical_enter();
    printf("[cluster %lu, core %lu] hello, team of %d\n", (unsigned long)pi_cluster_id(),
           (unsigned long)pi_core_id(), pi_cl_team_nb_cores());
    pi_cl_team_critical_exit();
}

static void master(void *arg)
{
    (void)arg;
    pi_cl_team_fork(0, hello, NULL); /* 0: every core */
}

int main(void)
{
    struct pi_device cluster;
    struct pi_cluster_conf conf;
    struct pi_cluster_task task;

    printf("[fc: cluster %lu, core %lu] opening the cluster\n", (unsigned long)pi_cluster_id(),
           (unsigned long)pi_core_id());
    pi_cluster_conf_init(&conf);
    pi_open_from_conf(&cluster, &conf);
    if (pi_cluster_open(&cluster) != 0) {
        printf("cannot open the cluster\n");
        return 1;
    }
    pi_cluster_send_task_to_cl(&cluster, pi_cluster_task(&task, master, NULL));
    pi_cluster_close(&cluster);
    printf("[fc] done\n");
    return 0;
}
